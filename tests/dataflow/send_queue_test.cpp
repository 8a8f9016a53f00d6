// The sending queue: per destination oldest first, a full pool refuses, a
// destination that refuses keeps its rays and order, slots are reused.
#include <doctest/doctest.h>

#include <algorithm>
#include <vector>

#include "dataflow/send_queue.h"
#include "nodes/arena.h"

using raynode::dataflow::RayMsg;
using raynode::dataflow::SendQueue;

namespace {

RayMsg ray(std::uint32_t region, std::uint32_t pixel) {
  RayMsg m{};
  m.region = region;
  m.pixel = pixel;
  return m;
}

}  // namespace

TEST_CASE("send queue: rays leave per destination oldest first, a full destination keeps its rays in order") {
  raynode::nodes::Arena arena(0, 1 << 20);
  SendQueue q(arena, 5, 3);
  CHECK(q.capacity() == 5);
  CHECK(q.push(ray(2, 10)));
  CHECK(q.push(ray(0, 11)));
  CHECK(q.push(ray(2, 12)));
  CHECK(q.push(ray(1, 13)));
  CHECK(q.push(ray(2, 14)));
  CHECK_FALSE(q.push(ray(0, 15)));  // the pool is full
  CHECK(q.size() == 5);

  // Destination 2 takes one ray, then is full; 0 and 1 take all theirs.
  std::vector<std::uint32_t> sent;
  int room2 = 1;
  const std::size_t n = q.drain([&](const RayMsg& m) {
    if (m.region == 2 && room2-- <= 0) return false;
    sent.push_back(m.pixel);
    return true;
  });
  CHECK(n == 3);
  CHECK(q.size() == 2);
  CHECK(std::count(sent.begin(), sent.end(), 10u) == 1);  // 2's oldest
  CHECK(std::count(sent.begin(), sent.end(), 12u) == 0);
  CHECK(std::count(sent.begin(), sent.end(), 11u) == 1);
  CHECK(std::count(sent.begin(), sent.end(), 13u) == 1);

  // Freed slots are reused; 2's remaining rays leave in their order, after
  // them the new ray for 2.
  CHECK(q.push(ray(2, 16)));
  CHECK(q.push(ray(0, 17)));
  CHECK(q.push(ray(1, 18)));
  CHECK_FALSE(q.push(ray(1, 19)));
  sent.clear();
  CHECK(q.drain([&](const RayMsg& m) {
    sent.push_back(m.pixel);
    return true;
  }) == 5);
  CHECK(q.empty());
  std::vector<std::uint32_t> to2;
  for (std::uint32_t p : sent)
    if (p == 12 || p == 14 || p == 16) to2.push_back(p);
  CHECK(to2 == std::vector<std::uint32_t>{12, 14, 16});
  // Empty: a pass sends nothing.
  CHECK(q.drain([](const RayMsg&) { return true; }) == 0);
}

TEST_CASE("send queue: its slots and tables come from the node's arena") {
  raynode::nodes::Arena arena(0, 1 << 20);
  const std::size_t before = arena.used();
  {
    SendQueue q(arena, 100, 8);
    CHECK(arena.used() - before >= 100 * SendQueue::kSlotBytes + SendQueue::destination_bytes(8));
  }
  CHECK(arena.used() == before);
  raynode::nodes::Arena small(0, 1000);
  CHECK_THROWS_AS(SendQueue(small, 100, 8), raynode::nodes::ArenaExhausted);
}
