// Link contention (nodes/links.h, nodes/timeline.h): routes as long as the
// topology's hop counts, e-cube order on the hypercube, messages sharing a
// link at once wait for each other, others do not.
#include <doctest/doctest.h>

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <set>
#include <vector>

#include "nodes/links.h"
#include "nodes/machine.h"
#include "nodes/timeline.h"

using namespace raynode::nodes;

TEST_CASE("links: every route has hops(a, b) distinct links, for every topology") {
  for (TopologyKind kind : {TopologyKind::kHypercube, TopologyKind::kRing, TopologyKind::kTorus2D})
    for (std::uint32_t n : {1u, 2u, 7u, 12u, 16u}) {
      CAPTURE(topology_name(kind));
      CAPTURE(n);
      const Topology t(kind, n);
      const LinkNetwork net(t);
      std::vector<std::uint32_t> route;
      for (NodeId a = 0; a < n; ++a)
        for (NodeId b = 0; b < n; ++b) {
          net.route(a, b, route);
          CHECK(route.size() == t.hops(a, b));
          CHECK(std::set<std::uint32_t>(route.begin(), route.end()).size() == route.size());
          for (std::uint32_t l : route) CHECK(l < net.links());
        }
    }
}

TEST_CASE("links: e-cube routes correct the lowest differing address bit first") {
  const Topology t(TopologyKind::kHypercube, 16);
  const LinkNetwork net(t);
  std::vector<std::uint32_t> a, b;
  net.route(0, 3, a);  // 0 -> 1 -> 3
  net.route(1, 3, b);  // 1 -> 3
  REQUIRE(a.size() == 2);
  REQUIRE(b.size() == 1);
  CHECK(a[1] == b[0]);  // the two share the link 1 -> 3
  net.route(3, 1, b);   // the opposite direction is another link
  CHECK(b[0] != a[1]);
}

TEST_CASE("links: a message waits for a link another holds, while other links and directions do not") {
  const Topology t(TopologyKind::kHypercube, 8);
  LinkNetwork net(t);
  CHECK(net.reserve(0, 3, 1.0, 0.5) == 1.0);  // free: starts when ready
  CHECK(net.reserve(1, 3, 1.2, 0.5) == 1.5);  // shares 1 -> 3, held until 1.5
  CHECK(net.reserve(4, 5, 1.2, 0.5) == 1.2);  // another link
  CHECK(net.reserve(3, 1, 1.2, 0.5) == 1.2);  // the other direction
  CHECK(net.reserve(0, 1, 0.2, 0.5) == 0.2);  // booked later, earlier in virtual time: the gap before
  CHECK(net.reserve(0, 1, 0.6, 0.5) == 1.5);  // 0 -> 1 is held over [0.2, 0.7) and [1.0, 1.5): [0.7, 1.0) is too short
  net.cancel(0, 1, 1.5, 0.5);
  CHECK(net.reserve(0, 1, 1.6, 0.5) == 1.6);  // the cancelled period is free again
}

TEST_CASE("timeline: first fit, merged periods, cancel, and bounded memory") {
  BusyTimeline t;
  CHECK(t.take(1.0, 1.0) == 1.0);
  CHECK(t.take(0.0, 0.5) == 0.0);
  CHECK(t.take(0.2, 0.6) == 2.0);  // [0.5, 1.0) is too short; [2.0, 2.6) joins [1.0, 2.0)
  CHECK(t.periods() == 2);
  CHECK(t.take(0.5, 0.5) == 0.5);  // fits exactly, and joins both neighbours
  CHECK(t.periods() == 1);
  t.cancel(2.0, 0.6);  // [0, 2.6) -> [0, 2.0)
  CHECK(t.first_gap(1.9, 0.5) == 2.0);
  t.cancel(0.5, 0.5);  // a hole in the middle: [0, 0.5) and [1.0, 2.0)
  CHECK(t.periods() == 2);
  CHECK(t.first_gap(0.2, 0.5) == 0.5);
  CHECK(t.first_gap(0.2, 0.6) == 2.0);
  t.cancel(7.0, 1.0);  // never booked: nothing changes
  t.book(5.0, 0.0);    // zero length: nothing booked
  CHECK(t.periods() == 2);
  for (std::size_t i = 0; i < 2 * BusyTimeline::kMaxPeriods; ++i) t.take(10.0 + double(i), 0.5);
  CHECK(t.periods() <= BusyTimeline::kMaxPeriods);
  CHECK(t.periods() >= BusyTimeline::kMaxPeriods / 2);
}

TEST_CASE("links: under contention two 1 KiB messages over a shared link arrive one hold apart") {
  for (bool contention : {false, true}) {
    CAPTURE(contention);
    MachineParams p;
    p.nodes = 4;
    p.timeout_s = 60;
    p.max_payload = 2048;
    p.network.name = "test";
    p.network.latency_s = 1e-3;
    p.network.per_byte_s = 1e-6;
    p.network.contention = contention;
    Machine machine(p);
    std::vector<double> arrivals;
    std::atomic<int> sent{0};
    const RunReport r = machine.run(
        [&](NodeContext& ctx) {
          const std::vector<std::byte> page(1024);
          const std::span<const std::byte> parts[1] = {page};
          if (ctx.id() == 0 || ctx.id() == 1) {  // both at time 0; routes 0 -> 1 -> 3 and 1 -> 3
            ctx.send(3, MessageType::kPageReply, std::span<const std::span<const std::byte>>(parts, 1), 0.0);
            sent.fetch_add(1);
          } else if (ctx.id() == 3) {
            for (int i = 0; i < 2; ++i) arrivals.push_back(ctx.receive(WaitKind::kCommunication).header.arrival_time);
          }
        },
        [](NodeContext&) {});
    REQUIRE(arrivals.size() == 2);
    std::sort(arrivals.begin(), arrivals.end());
    const double hold = 1024 * 1e-6;
    CHECK(arrivals[0] == doctest::Approx(1e-3 + hold));
    if (contention) {
      CHECK(arrivals[1] == doctest::Approx(1e-3 + 2 * hold));
      CHECK(r.nodes[0].counters.link_waits + r.nodes[1].counters.link_waits == 1);
    } else {
      CHECK(arrivals[1] == doctest::Approx(1e-3 + hold));
      CHECK(r.nodes[0].counters.link_waits + r.nodes[1].counters.link_waits == 0);
    }
  }
}

TEST_CASE("network: a node's own send spends send_overhead of its CPU, an interrupt reply's is in its service") {
  MachineParams p;
  p.nodes = 2;
  p.timeout_s = 60;
  p.network.name = "test";
  p.network.latency_s = 10;        // large against any CPU time in the test
  p.network.send_overhead_s = 100;
  p.network.service_s = 1;
  CHECK(p.network.reply_service_s() == 101);
  Machine machine(p);
  double arrival = 0, reply_arrival = 0, sent_at = 0, clock_after_send = 0;
  const RunReport r = machine.run(
      [&](NodeContext& ctx) {
        const std::byte b{};
        const std::span<const std::byte> parts[1] = {std::span<const std::byte>(&b, 1)};
        const std::span<const std::span<const std::byte>> msg(parts, 1);
        if (ctx.id() == 0) {
          sent_at = ctx.now();
          ctx.send(1, MessageType::kTest, msg);  // own send: +100 s of CPU, then 10 s of wire
          clock_after_send = ctx.now();
          reply_arrival = ctx.receive(WaitKind::kCommunication).header.arrival_time;
        } else {
          const Message m = ctx.receive(WaitKind::kCommunication);
          arrival = m.header.arrival_time;
          // The reply as an interrupt handler sends it: departs when its service ends.
          const double at = ctx.serve_interrupt(arrival, ctx.network().reply_service_s());
          ctx.send(0, MessageType::kTest, msg, at);
        }
      },
      [](NodeContext&) {});
  CHECK(arrival >= sent_at + 110);
  CHECK(arrival <= sent_at + 110.05);
  CHECK(clock_after_send >= sent_at + 100);
  CHECK(r.nodes[0].counters.busy_s >= 100);
  CHECK(reply_arrival == doctest::Approx(arrival + 101 + 10));  // no second overhead on the reply
  CHECK(r.nodes[1].counters.busy_s >= 101);
  CHECK(r.nodes[1].counters.busy_s < 101 + 1);
}

TEST_CASE("timeline: first fit agrees with a plain list of busy periods over random bookings and cancels") {
  // The reference: every booking kept as its own period, searched linearly.
  struct Reference {
    std::vector<std::pair<double, double>> periods;
    bool free(double s, double e) const {
      for (const auto& [a, b] : periods)
        if (a < e && s < b) return false;
      return true;
    }
    double first_gap(double earliest, double length) const {
      std::vector<double> candidates{earliest};
      for (const auto& p : periods)
        if (p.second >= earliest) candidates.push_back(p.second);
      std::sort(candidates.begin(), candidates.end());
      for (double c : candidates)
        if (free(c, c + length)) return c;
      return -1;
    }
  };
  std::uint64_t seed = 12345;
  auto uniform = [&seed](double lo, double hi) {
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    return lo + (hi - lo) * double(seed >> 11) / double(1ull << 53);
  };
  BusyTimeline t;
  Reference ref;
  std::vector<std::pair<double, double>> booked;
  for (int i = 0; i < 3000; ++i) {
    if (!booked.empty() && uniform(0, 1) < 0.2) {  // cancel a random earlier booking
      const std::size_t k = std::size_t(uniform(0, double(booked.size())));
      const auto [s, len] = booked[std::min(k, booked.size() - 1)];
      t.cancel(s, len);
      ref.periods.erase(std::find(ref.periods.begin(), ref.periods.end(), std::make_pair(s, s + len)));
      booked.erase(std::find(booked.begin(), booked.end(), std::make_pair(s, len)));
      continue;
    }
    const double earliest = uniform(0, 100), length = uniform(0.01, 0.5);
    const double expected = ref.first_gap(earliest, length);
    const double got = t.take(earliest, length);
    REQUIRE(got == doctest::Approx(expected));
    ref.periods.emplace_back(got, got + length);
    booked.emplace_back(got, length);
  }
  CHECK(t.periods() <= BusyTimeline::kMaxPeriods);
}
