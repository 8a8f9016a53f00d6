#include <doctest/doctest.h>

#include <vector>

#include "nodes/scheduler.h"

using namespace raynode::nodes;

TEST_CASE("scheduler: K permits, the laggard gets the CPU once the runner is a window ahead") {
  std::vector<std::uint32_t> woken;
  Scheduler s(3, 1, 0.5, [&](std::uint32_t n) { woken.push_back(n); });
  REQUIRE(s.enabled());
  CHECK(s.try_run(0, 0.0));         // the free permit
  CHECK_FALSE(s.try_run(1, 0.2));   // queued at 0.2
  CHECK_FALSE(s.try_run(2, 0.1));   // queued at 0.1
  CHECK(s.yield_point(0, 0.55));    // 0.1 + 0.5 is not < 0.55: keep going
  CHECK(woken.empty());
  CHECK_FALSE(s.yield_point(0, 0.7));  // node 2 (0.1) is more than 0.5 behind: hand over to it
  REQUIRE(woken.size() == 1);
  CHECK(woken[0] == 2);
  CHECK(s.granted_flag(2).load());
  CHECK_FALSE(s.granted_flag(0).load());
  CHECK(s.try_run(2, 0.1));
  CHECK_FALSE(s.try_run(0, 0.7));  // still queued
  s.release(2);                    // node 2 blocks: the lowest queued (node 1 at 0.2) gets the permit
  REQUIRE(woken.size() == 2);
  CHECK(woken[1] == 1);
  CHECK(s.try_run(1, 0.2));
  s.release(1);
  CHECK(woken.back() == 0);
  s.release(0);
  CHECK(s.try_run(2, 5.0));  // the permit is free again
  CHECK(s.handoffs() == 1);
}

TEST_CASE("scheduler: disabled when there are at least as many permits as nodes, or with a negative window") {
  Scheduler a(2, 2, 0.1, [](std::uint32_t) {});
  CHECK_FALSE(a.enabled());
  CHECK(a.try_run(0, 0));
  CHECK(a.try_run(1, 100));
  CHECK(a.yield_point(1, 1e9));
  Scheduler b(8, 2, -1, [](std::uint32_t) {});
  CHECK_FALSE(b.enabled());
}
