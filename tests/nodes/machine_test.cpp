#include <doctest/doctest.h>

#include <atomic>
#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "nodes/machine.h"

using namespace raynode::nodes;

namespace {

struct Token {
  std::uint32_t laps;
  std::uint32_t visits;
};

/// A token travels the ring `laps` times; node 0 then tells the host.
void token_ring_node(NodeContext& ctx, std::uint32_t laps) {
  const NodeId next = ctx.topology().ring_next(ctx.id());
  if (ctx.id() == 0) ctx.send(next, MessageType::kToken, Token{0, 1});
  while (true) {
    const Message m = ctx.receive(WaitKind::kIdle);
    if (m.type() == MessageType::kShutdown) return;
    Token t = m.as<Token>();
    if (ctx.id() == 0 && ++t.laps == laps) {
      ctx.send(kHost, MessageType::kToken, t);
      continue;
    }
    ++t.visits;
    ctx.send(next, MessageType::kToken, t);
  }
}

void shutdown_after_token(NodeContext& host, Token& out) {
  const Message m = host.receive(WaitKind::kIdle);
  out = m.as<Token>();
  for (NodeId i = 0; i < host.node_count(); ++i) host.send(i, MessageType::kShutdown, Token{});
}

/// Runs a token ring of `laps` laps on a machine of `nodes` nodes; `result`
/// gets the token the host received.
RunReport run_token_ring(std::uint32_t nodes, std::uint32_t laps, Token& result) {
  MachineParams p;
  p.nodes = nodes;
  p.timeout_s = 60;
  Machine machine(p);
  return machine.run([laps](NodeContext& ctx) { token_ring_node(ctx, laps); },
                     [&](NodeContext& host) { shutdown_after_token(host, result); });
}

}  // namespace

TEST_CASE("machine: 256 nodes pass a token round the ring 3 times and all terminate cleanly") {
  Token result{};
  const RunReport r = run_token_ring(256, 3, result);
  CHECK(result.laps == 3);
  CHECK(result.visits == 3 * 256);  // 255 per lap, +1 at the start, +1 by node 0 on each lap but the last
  REQUIRE(r.nodes.size() == 256);
  const NodeCounters total = r.total();
  CHECK(total.sent[std::size_t(MessageType::kToken)].messages == 3 * 256 + 1);
  CHECK(total.received[std::size_t(MessageType::kShutdown)].messages == 256);
  CHECK(total.sent[std::size_t(MessageType::kToken)].bytes == (3 * 256 + 1) * sizeof(Token));
  for (const NodeReport& n : r.nodes) CHECK(n.counters.received[std::size_t(MessageType::kToken)].messages == 3);
}

TEST_CASE("machine: the JSON totals list every message type, zeros included, the host and nodes only those they used") {
  Token result{};
  const RunReport r = run_token_ring(4, 1, result);
  const nlohmann::json j = r.to_json(true);
  const NodeCounters counts = r.total();
  for (const std::string side : {"sent", "received"}) {
    CAPTURE(side);
    const nlohmann::json& total = j["total"][side];
    CHECK(total.size() == kMessageTypeCount);
    for (std::size_t i = 0; i < kMessageTypeCount; ++i) {
      const std::string name = message_type_name(MessageType(i));
      CAPTURE(name);
      REQUIRE(total.contains(name));
      const MessageCounts& c = side == "sent" ? counts.sent[i] : counts.received[i];
      CHECK(total[name]["messages"] == c.messages);
      CHECK(total[name]["bytes"] == c.bytes);
    }
    CHECK(total["page_request"]["messages"] == 0);  // a token ring asks for no page
  }
  CHECK(j["total"]["sent"]["token"]["messages"] == 5);      // 4 round the ring, 1 to the host
  CHECK(j["total"]["received"]["token"]["messages"] == 4);  // the host's is not a node's
  // The host sent only shutdowns, and received only the token.
  CHECK(j["host"]["sent"].size() == 1);
  CHECK(j["host"]["sent"]["shutdown"]["messages"] == 4);
  CHECK(j["host"]["received"].size() == 1);
  for (const nlohmann::json& n : j["per_node"]) {
    CHECK_FALSE(n["sent"].contains("page_request"));
    CHECK(n["received"]["shutdown"]["messages"] == 1);
  }
}

TEST_CASE("machine: an exception in one node stops the run and reaches the caller with the node id") {
  MachineParams p;
  p.nodes = 8;
  p.timeout_s = 60;
  Machine machine(p);
  try {
    machine.run(
        [](NodeContext& ctx) {
          if (ctx.id() == 5) throw std::runtime_error("boom in the tracer");
          ctx.receive(WaitKind::kIdle);  // everyone else blocks: must be woken
        },
        [](NodeContext& host) { host.receive(WaitKind::kIdle); });
    FAIL("run must throw");
  } catch (const NodeError& e) {
    CHECK(e.node == 5);
    CHECK(std::string(e.what()) == "node 5: boom in the tracer");
  }
}

TEST_CASE("machine: a node that exceeds its memory fails the run with the sizes named") {
  MachineParams p;
  p.nodes = 4;
  p.node_memory = 64 * 1024;
  p.timeout_s = 60;
  Machine machine(p);
  try {
    machine.run(
        [](NodeContext& ctx) {
          if (ctx.id() == 2) ArenaArray<char> big(ctx.arena(), 100000, "its page cache");
          ctx.receive(WaitKind::kIdle);
        },
        [](NodeContext& host) { host.receive(WaitKind::kIdle); });
    FAIL("run must throw");
  } catch (const NodeError& e) {
    CHECK(e.node == 2);
    const std::string what = e.what();
    CHECK(what.rfind("node 2: out of node memory: its page cache needs", 0) == 0);
    CHECK(what.find("64 KiB") != std::string::npos);
  }
}

TEST_CASE("machine: the watchdog stops a run that would hang") {
  MachineParams p;
  p.nodes = 3;
  p.timeout_s = 0.3;
  Machine machine(p);
  CHECK_THROWS_WITH_AS(machine.run([](NodeContext& ctx) { ctx.receive(WaitKind::kIdle); },
                                   [](NodeContext& host) { host.receive(WaitKind::kIdle); }),
                       doctest::Contains("watchdog"), NodeError);
}

TEST_CASE("machine: sending to a node that does not exist is an error, not a crash") {
  MachineParams p;
  p.nodes = 2;
  p.timeout_s = 60;
  Machine machine(p);
  CHECK_THROWS_WITH_AS(machine.run([](NodeContext& ctx) { if (ctx.id() == 1) ctx.send(7, MessageType::kTest, Token{}); },
                                   [](NodeContext&) {}),
                       doctest::Contains("node 7, but the machine has 2 nodes"), NodeError);
}

TEST_CASE("machine: virtual time follows the network model — arrival = send + latency + bytes x per-byte + hops x per-hop") {
  MachineParams p;
  p.nodes = 8;
  p.topology = TopologyKind::kHypercube;
  p.network.name = "test";
  p.network.latency_s = 100;     // large against any CPU time in the test
  p.network.per_byte_s = 1;
  p.network.per_hop_s = 1000;
  p.timeout_s = 60;
  Machine machine(p);
  std::vector<double> arrival(8, 0), sent_at(8, 0), clock_after(8, 0);
  const RunReport r = machine.run(
      [&](NodeContext& ctx) {
        if (ctx.id() == 0) {
          for (NodeId d = 1; d < 8; ++d) {
            sent_at[d] = ctx.now();
            ctx.send(d, MessageType::kTest, Token{});  // 8 bytes
          }
        } else {
          const Message m = ctx.receive(WaitKind::kCommunication);
          arrival[ctx.id()] = m.header.arrival_time;
          clock_after[ctx.id()] = ctx.now();
        }
      },
      [](NodeContext&) {});
  for (NodeId d = 1; d < 8; ++d) {
    const double hops = double(Topology(TopologyKind::kHypercube, 8).hops(0, d));
    // The send departs a few microseconds of CPU time after now() was read.
    const double expected = sent_at[d] + 100 + 8 * 1 + hops * 1000;
    CHECK(arrival[d] >= expected);
    CHECK(arrival[d] <= expected + 0.05);
    CHECK(clock_after[d] >= arrival[d]);
    CHECK(r.nodes[d].counters.communication_s >= arrival[d] - 1.0);  // waited for it (minus CPU time, < 1 s)
  }
  CHECK(r.parallel_time_s >= 100 + 8 + 3 * 1000);  // node 7 is 3 hops away
}

TEST_CASE("machine: two nodes flooding each other's small mailboxes do not deadlock") {
  MachineParams p;
  p.nodes = 2;
  p.mailbox_capacity = 2;
  p.timeout_s = 60;
  Machine machine(p);
  constexpr std::uint32_t kCount = 5000;
  std::vector<std::uint32_t> got(2, 0);
  machine.run(
      [&](NodeContext& ctx) {
        const NodeId other = 1 - ctx.id();
        for (std::uint32_t i = 0; i < kCount; ++i) ctx.send(other, MessageType::kTest, Token{i, 0});
        std::uint32_t expect = 0;
        while (expect < kCount) {
          const Message m = ctx.receive(WaitKind::kIdle);
          if (m.as<Token>().laps == expect) ++expect;
          else break;
        }
        got[ctx.id()] = expect;
        ctx.send(kHost, MessageType::kNodeDone, Token{});
        ctx.receive(WaitKind::kIdle);  // shutdown
      },
      [](NodeContext& host) {
        for (int i = 0; i < 2; ++i) host.receive(WaitKind::kIdle);
        for (NodeId n = 0; n < 2; ++n) host.send(n, MessageType::kShutdown, Token{});
      });
  CHECK(got[0] == kCount);
  CHECK(got[1] == kCount);
}

namespace {

/// Node 0 blocks sending kToHost messages to a host that starts draining
/// only after a pause, while node 1 floods node 0 (try_send, never
/// blocking). Returns node 0's parking peak; checks every message arrives.
std::uint64_t park_peak(std::size_t limit) {
  MachineParams p;
  p.nodes = 2;
  p.mailbox_capacity = 4;
  p.host_mailbox_capacity = 2;
  p.timeout_s = 60;
  Machine machine(p);
  constexpr std::uint32_t kToHost = 40, kFlood = 300;
  std::uint32_t received = 0;
  const RunReport report = machine.run(
      [&](NodeContext& ctx) {
        if (ctx.id() == 0) {
          if (limit) ctx.set_park_limit(limit);
          for (std::uint32_t i = 0; i < kToHost; ++i) ctx.send(kHost, MessageType::kTest, Token{i, 0});
          std::uint32_t expect = 0;
          while (expect < kFlood && ctx.receive(WaitKind::kIdle).as<Token>().laps == expect) ++expect;
          received = expect;
        } else {
          for (std::uint32_t i = 0; i < kFlood; ++i)
            while (!ctx.try_send(0, MessageType::kTest, Token{i, 0})) std::this_thread::yield();
        }
        ctx.send(kHost, MessageType::kNodeDone, Token{});
        ctx.receive(WaitKind::kIdle);  // shutdown
      },
      [&](NodeContext& host) {
        std::this_thread::sleep_for(std::chrono::milliseconds(100));  // node 0's sends wait meanwhile
        std::uint32_t done = 0;
        while (done < 2)
          if (host.receive(WaitKind::kIdle).type() == MessageType::kNodeDone) ++done;
        for (NodeId n = 0; n < 2; ++n) host.send(n, MessageType::kShutdown, Token{});
      });
  CHECK(received == kFlood);  // in order, none lost
  return report.nodes[0].counters.backlog_peak;
}

}  // namespace

TEST_CASE("machine: a blocked send parks at most set_park_limit() messages, and none is lost") {
  CHECK(park_peak(3) <= 3);
  CHECK(park_peak(0) > 3);  // control: unbounded, it parks what the flood brings
}

TEST_CASE("machine: bad parameters and byte sizes are refused with a message") {
  MachineParams p;
  p.nodes = 0;
  CHECK_THROWS_AS(Machine{p}, std::invalid_argument);
  CHECK(parse_bytes("4MiB") == 4u << 20);
  CHECK(parse_bytes("512KiB") == 512u << 10);
  CHECK(parse_bytes("65536") == 65536);
  CHECK(parse_bytes("2m") == 2u << 20);
  CHECK_THROWS_AS(parse_bytes("four"), std::invalid_argument);
  CHECK_THROWS_AS(parse_bytes("4TiB"), std::invalid_argument);
  CHECK_THROWS_AS(parse_bytes("0"), std::invalid_argument);
}

TEST_CASE("machine: the stall watchdog stops a run that sends nothing and says what each node waits for") {
  MachineParams p;
  p.nodes = 4;
  p.stall_timeout_s = 0.3;
  p.timeout_s = 60;
  Machine machine(p);
  const auto t0 = std::chrono::steady_clock::now();
  try {
    machine.run(
        [](NodeContext& ctx) {
          if (ctx.id() == 3) return;  // finishes at once
          if (ctx.id() == 1) ctx.note_wait(WaitReason::kPage, 17, 2);
          if (ctx.id() == 2) ctx.send(0, MessageType::kTest, std::uint64_t{1});  // progress, then silence
          ctx.receive(WaitKind::kIdle);  // 1 and 2 wait for mail that never comes
          if (ctx.id() == 0) ctx.receive(WaitKind::kIdle);
        },
        [](NodeContext& host) { host.receive(WaitKind::kIdle); });
    FAIL("run must throw");
  } catch (const NodeError& e) {
    const std::string what = e.what();
    CAPTURE(what);
    CHECK(e.node == kHost);
    CHECK(what.find("no message was sent") != std::string::npos);
    CHECK(what.find("node 0: waiting for mail") != std::string::npos);
    CHECK(what.find("node 1: waiting for page 17 from node 2") != std::string::npos);
    CHECK(what.find("node 2: waiting for mail") != std::string::npos);
    CHECK(what.find("node 3:") == std::string::npos);  // finished nodes are only counted
    CHECK(what.find("1 nodes finished") != std::string::npos);
  }
  const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  CHECK(waited < 30);  // the stall watchdog, not the 60 s timeout, ended it
}

TEST_CASE("machine: the host's nap grows while its mail stays short, and a gathering host lets pixels queue") {
  const std::uint32_t cap = 4096;
  // Nothing came: the nap doubles up to the cap, whatever the host does.
  CHECK(next_host_nap(kHostNapMinS, 0, cap, false) == doctest::Approx(2 * kHostNapMinS));
  CHECK(next_host_nap(kHostNapMaxS, 0, cap, true) == kHostNapMaxS);
  double nap = kHostNapMinS;
  for (int i = 0; i < 20; ++i) nap = next_host_nap(nap, 0, cap, false);
  CHECK(nap == kHostNapMaxS);
  // A host that answers looks again soon after any message.
  CHECK(next_host_nap(kHostNapMaxS, 1, cap, false) == kHostNapMinS);
  // A gathering host: a short queue (under 1/16) still doubles its nap...
  nap = kHostNapMinS;
  for (int i = 0; i < 20; ++i) nap = next_host_nap(nap, cap / 16 - 1, cap, true);
  CHECK(nap == kHostNapMaxS);
  // ...between 1/16 and 1/4 it holds...
  CHECK(next_host_nap(4 * kHostNapMinS, cap / 16, cap, true) == doctest::Approx(4 * kHostNapMinS));
  CHECK(next_host_nap(4 * kHostNapMinS, cap / 4 - 1, cap, true) == doctest::Approx(4 * kHostNapMinS));
  // ...and from a quarter full it looks again soon, before senders find it full.
  CHECK(next_host_nap(kHostNapMaxS, cap / 4, cap, true) == kHostNapMinS);
  CHECK(next_host_nap(kHostNapMaxS, cap, cap, true) == kHostNapMinS);
}

TEST_CASE("machine: under scheduled mail a sleeping node without a permit does not read its mail, so a pager must not spin on it") {
  // svm's page fault spins a while for the reply, holding its permit, only
  // where the home node reads its mail without a permit (svm/pager.cpp):
  // with every permit held by spinning nodes, a scheduled home could never
  // answer until each spin ran out.
  for (const bool scheduled : {true, false}) {
    CAPTURE(scheduled);
    MachineParams p;
    p.nodes = 3;
    p.run_permits = 1;
    p.scheduled_mail = scheduled;
    p.timeout_s = 60;
    Machine machine(p);
    std::atomic<int> peer1{-1}, peer2{-1}, host{-1};
    machine.run(
        [&](NodeContext& ctx) {
          if (ctx.id() != 0) {
            ctx.receive(WaitKind::kIdle);  // sleeps, holding no permit, until node 0's message
            return;
          }
          while (!ctx.try_run()) ctx.wait_for_mail(0);  // node 0 holds the one permit
          peer1 = ctx.peer_reads_mail(1);
          peer2 = ctx.peer_reads_mail(2);
          host = ctx.peer_reads_mail(kHost);
          ctx.send(1, MessageType::kTest, std::uint64_t{1});
          ctx.send(2, MessageType::kTest, std::uint64_t{2});
          ctx.release_run();
        },
        [](NodeContext&) {});
    CHECK(host == 1);  // the host is outside the scheduler
    CHECK(peer1 == (scheduled ? 0 : 1));
    CHECK(peer2 == (scheduled ? 0 : 1));
  }
}

TEST_CASE("machine: a byte size that does not fit 64 bits is refused with the value and the maximum, never wrapped") {
  // 17179869185 GiB = 2^64 + 2^30 B wrapped to 1 GiB before the check.
  try {
    parse_bytes("17179869185GiB");
    FAIL("17179869185GiB was accepted");
  } catch (const std::invalid_argument& e) {
    CHECK(std::string(e.what()) ==
          "byte size '17179869185GiB' is too large: at most 4294967296 GiB (4611686018427387904 B)");
  }
  CHECK_THROWS_AS(parse_bytes("99999999999999999999999999"), std::invalid_argument);  // overflows the digits
  CHECK_THROWS_AS(parse_bytes("4294967297GiB"), std::invalid_argument);              // just above 2^62
  CHECK(parse_bytes("4294967296GiB") == kMaxByteSize);                                // the maximum itself
  CHECK(parse_bytes("1234567890123456") == 1234567890123456u);  // 16 digits, once refused as malformed
  CHECK(parse_bytes("0004KiB") == 4096u);
}

TEST_CASE("machine: nodes x node memory beyond the host's memory is refused before anything is allocated") {
  // The rule itself, with the host's memory given.
  CHECK_NOTHROW(check_nodes_fit_host(64, 16 * kMiB, std::size_t(1) << 30));  // exactly the host: fits
  try {
    check_nodes_fit_host(256, std::size_t(64) << 30, std::size_t(23) << 30);
    FAIL("256 x 64 GiB on a 23 GiB host was accepted");
  } catch (const std::invalid_argument& e) {
    CHECK(std::string(e.what()).rfind("--nodes 256 x --node-memory 64 GiB = 16384 GiB, more than this host's "
                                      "23 GiB of physical memory",
                                      0) == 0);
  }
  CHECK_THROWS_AS(check_nodes_fit_host(65, 16 * kMiB, std::size_t(1) << 30), std::invalid_argument);
  // The product does not wrap: 4096 x 4 EiB is far above any host.
  CHECK_THROWS_AS(check_nodes_fit_host(4096, kMaxByteSize, std::size_t(1) << 40), std::invalid_argument);
  CHECK_NOTHROW(check_nodes_fit_host(4096, kMaxByteSize, 0));  // host memory unknown: no check
  // Machine applies it with this host's memory: 4096 nodes of 4 EiB never fit.
  REQUIRE(host_physical_memory() > 0);
  MachineParams p;
  p.nodes = 4096;
  p.node_memory = kMaxByteSize;
  CHECK_THROWS_WITH_AS(Machine{p}, doctest::Contains("of physical memory"), std::invalid_argument);
  p.nodes = 64;
  p.node_memory = 16 * kMiB;  // 1 GiB in all: a sane run still starts
  CHECK_NOTHROW(Machine{p});
}

TEST_CASE("machine: a node's interrupt handler serves one message at a time, each in the first gap after its arrival") {
  MachineParams p;
  p.nodes = 1;
  p.timeout_s = 60;
  Machine machine(p);
  std::vector<double> ends;
  const RunReport r = machine.run(
      [&](NodeContext& ctx) {
        ends.push_back(ctx.serve_interrupt(1.0, 0.5));  // an idle handler: arrival + service
        ends.push_back(ctx.serve_interrupt(1.2, 0.5));  // arrives while the first is served: queues
        ends.push_back(ctx.serve_interrupt(0.1, 0.5));  // taken later, arrived earlier: the gap before
        ends.push_back(ctx.serve_interrupt(0.3, 0.5));  // the gap [0.6, 1.0) is too short: after 2.0
        ends.push_back(ctx.serve_interrupt(0.6, 0.4));  // fits [0.6, 1.0) exactly
        ends.push_back(ctx.serve_interrupt(0.7, 0.0));  // a free service occupies nothing
      },
      [](NodeContext&) {});
  REQUIRE(ends.size() == 6);
  CHECK(ends[0] == doctest::Approx(1.5));
  CHECK(ends[1] == doctest::Approx(2.0));
  CHECK(ends[2] == doctest::Approx(0.6));
  CHECK(ends[3] == doctest::Approx(2.5));
  CHECK(ends[4] == doctest::Approx(1.0));
  CHECK(ends[5] == doctest::Approx(0.7));
  const NodeCounters& c = r.nodes[0].counters;
  CHECK(c.services == 6);
  CHECK(c.service_wait_s == doctest::Approx(0.3 + 1.7));
  CHECK(c.busy_s >= 0.5 + 0.5 + 0.5 + 0.5 + 0.4);  // every service is charged to the server
}

TEST_CASE("machine: real time blocked for mail is booked as idle, or as communication while waiting for a page") {
  MachineParams p;
  p.nodes = 2;
  p.timeout_s = 60;
  Machine machine(p);
  const RunReport r = machine.run(
      [](NodeContext& ctx) {
        if (ctx.id() == 1) ctx.note_wait(WaitReason::kPage, 7, 0);
        ctx.receive(WaitKind::kIdle);
        ctx.note_wait(WaitReason::kNone);
      },
      [](NodeContext& host) {
        std::this_thread::sleep_for(std::chrono::milliseconds(40));
        for (NodeId i = 0; i < 2; ++i) host.send(i, MessageType::kShutdown, Token{});
      });
  REQUIRE(r.nodes.size() == 2);
  CHECK(r.nodes[0].counters.idle_wall_s >= 0.03);
  CHECK(r.nodes[0].counters.communication_wall_s == 0);
  CHECK(r.nodes[1].counters.communication_wall_s >= 0.03);
  CHECK(r.nodes[1].counters.idle_wall_s == 0);
  for (const NodeReport& n : r.nodes) CHECK(n.wall_s >= n.counters.idle_wall_s + n.counters.communication_wall_s);
}
