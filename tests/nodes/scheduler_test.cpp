#include <doctest/doctest.h>

#include <algorithm>
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
  CHECK(s.yield_point(0, 0.55));    // not more than 0.5 ahead of node 2 (0.1): keep going
  CHECK(woken.empty());
  CHECK_FALSE(s.yield_point(0, 0.7));  // more than 0.5 ahead: the permit goes to the laggard, node 2
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
  s.release(1);  // node 1 done: node 0 is the only active node left
  CHECK(woken.back() == 0);
  s.release(0);
  CHECK(s.try_run(2, 5.0));  // everyone else inactive: runs whatever its clock
  CHECK(s.handoffs() == 1);
}

TEST_CASE("scheduler: with free permits a node still waits for an active node more than a window behind") {
  std::vector<std::uint32_t> woken;
  Scheduler s(2, 2, 0.1, [&](std::uint32_t n) { woken.push_back(n); });
  REQUIRE(s.enabled());
  CHECK(s.try_run(0, 0.0));  // both start queued at 0: both get a permit (node 1 is woken)
  CHECK(s.try_run(1, 0.0));
  woken.clear();
  CHECK_FALSE(s.yield_point(0, 0.5));  // node 1 is at 0: node 0 must wait although a permit is free
  CHECK(woken.empty());
  CHECK(s.yield_point(1, 0.3));  // node 1 catches up, but 0.5 > 0.3 + 0.1: node 0 still waits
  CHECK(woken.empty());
  CHECK(s.yield_point(1, 0.45));  // now 0.5 <= 0.45 + 0.1: node 0 is let go
  REQUIRE(woken.size() == 1);
  CHECK(woken[0] == 0);
  CHECK(s.try_run(0, 0.5));
}

TEST_CASE("scheduler: disabled for a single node or a negative window") {
  Scheduler a(1, 2, 0.1, [](std::uint32_t) {});
  CHECK_FALSE(a.enabled());
  CHECK(a.try_run(0, 100));
  CHECK(a.yield_point(0, 1e9));
  Scheduler b(8, 2, -1, [](std::uint32_t) {});
  CHECK_FALSE(b.enabled());
  CHECK(b.try_run(3, 0));
  CHECK(b.yield_point(3, 1e9));
}

TEST_CASE("scheduler: a node awaiting a reply holds the others back, resuming inside a work unit ignores the window") {
  std::vector<std::uint32_t> woken;
  Scheduler s(3, 2, 0.1, [&](std::uint32_t n) { woken.push_back(n); });
  CHECK(s.try_run(0, 0.0));
  CHECK(s.try_run(1, 0.0));
  s.release(2);           // node 2 blocks for mail (it held nobody back)
  s.await_reply(0, 0.2);  // node 0 sent a request at 0.2 and blocks for the answer
  CHECK_FALSE(s.yield_point(1, 0.5));  // 0.5 > 0.2 + 0.1: node 1 may not run ahead of the awaiting node
  CHECK_FALSE(s.try_run(2, 0.4));      // nor may node 2, although two permits are free
  woken.clear();
  CHECK(s.try_run(0, 0.25));  // the reply came: node 0 runs again (lowest clock)
  // A node resuming after a page fault gets a free permit whatever its clock.
  CHECK(s.try_run(2, 0.4, true));
  s.release(0);  // node 0 done: node 1 (0.5) is within the window of node 2 (0.4)
  CHECK(std::find(woken.begin(), woken.end(), 1u) != woken.end());
}

TEST_CASE("scheduler: a node awaiting work holds the others at its clock, a node awaiting a page by the window") {
  std::vector<std::uint32_t> woken;
  Scheduler s(3, 2, 0.1, [&](std::uint32_t n) { woken.push_back(n); });
  CHECK(s.try_run(0, 0.0));
  CHECK(s.try_run(1, 0.0));
  s.release(2);
  s.await_reply(0, 0.2, Awaited::kWork);  // node 0 asked for work at 0.2
  CHECK(s.yield_point(1, 0.2));           // up to its clock, node 1 computes on
  CHECK_FALSE(s.yield_point(1, 0.25));    // within the window, but past a node awaiting work
  CHECK_FALSE(s.try_run(2, 0.21));
  CHECK(s.describe().find("(work)") != std::string::npos);
  woken.clear();
  CHECK(s.try_run(0, 0.22));  // the grant came: node 0 runs again (lowest clock)
  s.await_reply(0, 0.22);     // now it awaits a page: the others may run a window ahead
  CHECK(std::find(woken.begin(), woken.end(), 1u) != woken.end());  // node 1 (0.25) may run again
  CHECK(s.try_run(1, 0.25));
  CHECK(s.try_run(2, 0.3));
  CHECK_FALSE(s.yield_point(2, 0.33));  // past 0.22 + 0.1
}

TEST_CASE("scheduler: a sleeping node's mail gets a service permit before queued compute, and gives it back") {
  std::vector<std::uint32_t> woken;
  Scheduler s(4, 1, 0.1, [&](std::uint32_t n) { woken.push_back(n); }, true);
  REQUIRE(s.scheduled_mail());
  CHECK(s.try_run(0, 0.0));        // node 0 computes with the only permit
  CHECK_FALSE(s.try_run(1, 0.0));  // node 1 may run, but waits for the permit
  s.release(2);
  s.release(3);
  woken.clear();
  s.note_mail(2);  // no free permit: node 2 sleeps on
  s.note_mail(2);  // more mail: still one request for service
  s.note_mail(0);  // node 0 holds a permit and polls itself: nothing to do
  CHECK(woken.empty());
  CHECK_FALSE(s.serving_flag(2).load());
  s.release(0);  // the permit goes to node 2's mail before node 1's compute
  REQUIRE(woken.size() == 1);
  CHECK(woken[0] == 2);
  CHECK(s.serving_flag(2).load());
  CHECK_FALSE(s.granted_flag(2).load());  // a service permit, not a compute one
  CHECK_FALSE(s.granted_flag(1).load());
  s.end_service(2);  // served: the permit goes on to node 1
  CHECK_FALSE(s.serving_flag(2).load());
  CHECK(woken.back() == 1);
  CHECK(s.granted_flag(1).load());
  CHECK(s.service_grants() == 1);
  // A sender blocked on node 3's full mailbox forces service although the
  // one permit is taken; it comes back at end_service without being handed on.
  s.note_mail(3, true);
  CHECK(s.serving_flag(3).load());
  CHECK(s.granted_flag(1).load());
  s.end_service(3);
  CHECK(s.service_grants() == 2);
  // A serving node that asks to compute trades its service permit in.
  s.note_mail(2, true);
  CHECK(s.serving_flag(2).load());
  CHECK_FALSE(s.try_run(2, 0.5));  // not eligible: 0.5 > 0.0 + 0.1 (node 1 is active at 0)
  CHECK_FALSE(s.serving_flag(2).load());
  // A retired node's mail is never served.
  s.retire(3);
  s.release(1);  // the permit is free and node 2 is the only active node left: it runs
  CHECK(s.granted_flag(2).load());
  s.release(2);
  s.note_mail(3);
  CHECK_FALSE(s.serving_flag(3).load());
}

TEST_CASE("scheduler: mail service is off without scheduling") {
  Scheduler a(4, 2, -1, [](std::uint32_t) {}, true);
  CHECK_FALSE(a.scheduled_mail());
  Scheduler b(4, 2, 0.1, [](std::uint32_t) {}, false);
  CHECK_FALSE(b.scheduled_mail());
  b.note_mail(1);
  CHECK_FALSE(b.serving_flag(1).load());
}
