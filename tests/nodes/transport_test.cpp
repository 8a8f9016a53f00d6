// The machine over a transport (nodes/transport.h), without MPI: a loopback
// transport joins several "processes" (threads of this test, each running
// Machine::run for its own node) through in-memory queues. The same node
// programs must see the same messages as on the in-process machine, and
// process 0 must get every node's report.
#include <doctest/doctest.h>

#include <barrier>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "nodes/machine.h"

using namespace raynode::nodes;

namespace {

/// What every loopback endpoint shares: a queue per process, and a barrier
/// for the collectives.
struct Hub {
  struct Packet {
    NodeId dest;
    MessageHeader header;
    std::vector<std::byte> payload;
  };
  explicit Hub(std::uint32_t processes) : queues(processes), sync(std::ptrdiff_t(processes)), slots(processes) {}
  std::mutex mutex;
  std::vector<std::deque<Packet>> queues;
  std::barrier<> sync;
  std::vector<std::vector<std::byte>> slots;  ///< gather: each process's bytes
};

class LoopbackTransport final : public Transport {
 public:
  LoopbackTransport(Hub& hub, std::uint32_t process) : hub_(hub), process_(process) {}
  ~LoopbackTransport() override { stop(); }

  std::string name() const override { return "loopback"; }
  std::uint32_t processes() const override { return std::uint32_t(hub_.queues.size()); }
  std::uint32_t process() const override { return process_; }
  std::uint32_t process_of(NodeId id, std::uint32_t) const override { return id == kHost ? 0 : id; }

  void start(Deliver deliver) override {
    deliver_ = std::move(deliver);
    stopping_ = false;
    receiver_ = std::thread([this] {
      while (!stopping_.load())
        if (!receive_one(true)) std::this_thread::sleep_for(std::chrono::microseconds(20));
    });
    hub_.sync.arrive_and_wait();
  }
  void send(NodeId dest, const MessageHeader& header, std::span<const std::span<const std::byte>> parts,
            std::uint32_t nodes) override {
    Hub::Packet p{dest, header, {}};
    for (const auto& part : parts) p.payload.insert(p.payload.end(), part.begin(), part.end());
    std::lock_guard<std::mutex> lock(hub_.mutex);
    hub_.queues[process_of(dest, nodes)].push_back(std::move(p));
    ++sent_;
  }
  bool poll() override { return receive_one(false); }
  bool receive_one(bool wait) {
    // Held from taking a packet to delivering it: one sender's packets are
    // delivered in order. A participant's poll gives up when it is held.
    std::unique_lock<std::mutex> order(order_, std::defer_lock);
    if (wait) order.lock();
    else if (!order.try_lock()) return false;
    const bool gated = std::this_thread::get_id() != ungated_.load();
    if (gated && gate_ == 0) return false;
    Hub::Packet p;
    {
      std::lock_guard<std::mutex> lock(hub_.mutex);
      auto& q = hub_.queues[process_];
      if (q.empty()) return false;
      p = std::move(q.front());
      q.pop_front();
    }
    if (gated && gate_ > 0) --gate_;
    deliver_(p.dest, p.header, p.payload);
    delivered_.fetch_add(1);
    return true;
  }
  void finish() override {
    hub_.sync.arrive_and_wait();  // every process's participants have ended: nothing more is sent
    while (receive_one(true)) {
    }
    stop();
  }
  void stop() noexcept override {
    stopping_ = true;
    if (receiver_.joinable()) receiver_.join();
  }
  void note_waiting(int) noexcept override {}
  void gather(std::span<const std::byte> mine, std::span<std::byte> all) override {
    hub_.slots[process_].assign(mine.begin(), mine.end());
    hub_.sync.arrive_and_wait();
    if (process_ == 0)
      for (std::size_t i = 0; i < hub_.slots.size(); ++i)
        std::memcpy(all.data() + i * mine.size(), hub_.slots[i].data(), mine.size());
    hub_.sync.arrive_and_wait();
  }
  std::uint64_t sent() const { return sent_; }
  /// Lets the threads other than the exempt one (the receiving thread, the
  /// participants' polls) deliver `packets` more (< 0: any number).
  void open_gate(int packets) {
    std::lock_guard<std::mutex> lock(order_);
    gate_ = packets;
  }
  /// The calling thread's polls are never held by the gate.
  void exempt_this_thread() { ungated_ = std::this_thread::get_id(); }
  /// Packets delivered so far, by either thread.
  std::uint64_t delivered() const { return delivered_.load(); }
  /// Packets waiting for this process.
  std::size_t queued() {
    std::lock_guard<std::mutex> lock(hub_.mutex);
    return hub_.queues[process_].size();
  }

 private:
  Hub& hub_;
  std::uint32_t process_;
  Deliver deliver_;
  std::mutex order_;
  std::thread receiver_;
  std::atomic<bool> stopping_{false};
  int gate_ = -1;  ///< open_gate(), under order_
  std::atomic<std::thread::id> ungated_{};
  std::atomic<std::uint64_t> delivered_{0};
  std::uint64_t sent_ = 0;
};

struct Hello {
  std::uint32_t from;
  std::uint32_t round;
};

/// Every node sends `rounds` messages to every other node, then tells the
/// host how many it received; the host shuts them down once all reported.
void all_to_all_node(NodeContext& ctx, std::uint32_t rounds) {
  const std::uint32_t n = ctx.node_count();
  for (std::uint32_t r = 0; r < rounds; ++r)
    for (NodeId to = 0; to < n; ++to)
      if (to != ctx.id()) ctx.send(to, MessageType::kTest, Hello{ctx.id(), r});
  std::uint32_t got = 0;
  std::vector<std::uint32_t> next_round(n, 0);
  while (got < rounds * (n - 1)) {
    const Message m = ctx.receive(WaitKind::kIdle);
    REQUIRE(m.type() == MessageType::kTest);
    const Hello h = m.as<Hello>();
    CHECK(h.round == next_round[h.from]);  // one sender's messages arrive in order
    ++next_round[h.from];
    ++got;
  }
  ctx.send(kHost, MessageType::kNodeDone, Hello{ctx.id(), got});
  while (ctx.receive(WaitKind::kIdle).type() != MessageType::kShutdown) {
  }
}

void gathering_host(NodeContext& host, std::vector<std::uint32_t>& reported) {
  reported.assign(host.node_count(), 0);
  for (std::uint32_t i = 0; i < host.node_count(); ++i) {
    const Hello h = host.receive(WaitKind::kIdle).as<Hello>();
    reported.at(h.from) = h.round;
  }
  for (NodeId i = 0; i < host.node_count(); ++i) host.send(i, MessageType::kShutdown, Hello{});
}

}  // namespace

TEST_CASE("transport: 4 processes over a loopback transport run all-to-all as the in-process machine does") {
  constexpr std::uint32_t kNodes = 4, kRounds = 50;
  MachineParams base;
  base.nodes = kNodes;
  base.mailbox_capacity = 4;  // full mailboxes on the receiving side: accept() parks, deliveries wait
  base.timeout_s = 60;

  // The in-process machine: the reference counts.
  std::vector<std::uint32_t> local_reported;
  const RunReport local = Machine(base).run([&](NodeContext& ctx) { all_to_all_node(ctx, kRounds); },
                                            [&](NodeContext& host) { gathering_host(host, local_reported); });

  Hub hub(kNodes);
  std::vector<std::unique_ptr<LoopbackTransport>> transports;
  for (std::uint32_t p = 0; p < kNodes; ++p) transports.push_back(std::make_unique<LoopbackTransport>(hub, p));
  std::vector<RunReport> reports(kNodes);
  std::vector<std::uint32_t> reported;
  std::vector<std::uint32_t> per_node_value(kNodes, 0);
  std::vector<std::thread> processes;
  for (std::uint32_t p = 0; p < kNodes; ++p)
    processes.emplace_back([&, p] {
      MachineParams mp = base;
      mp.transport = transports[p].get();
      Machine machine(mp);
      std::vector<std::uint32_t> value(kNodes, 0);
      reports[p] = machine.run([&](NodeContext& ctx) { all_to_all_node(ctx, kRounds); },
                               [&](NodeContext& host) { gathering_host(host, reported); }, {},
                               [&](NodeContext& ctx) { value[ctx.id()] = 1000 + ctx.id(); });
      machine.gather(value);
      if (p == 0) per_node_value = value;
    });
  for (std::thread& t : processes) t.join();

  const std::size_t test = std::size_t(MessageType::kTest);
  CHECK(reported == local_reported);
  CHECK(reported == std::vector<std::uint32_t>(kNodes, kRounds * (kNodes - 1)));
  // Process 0 has every node's report and gathered value; the in-process run's counts agree.
  const RunReport& r = reports[0];
  CHECK(r.transport == "loopback");
  REQUIRE(r.nodes.size() == kNodes);
  for (std::uint32_t i = 0; i < kNodes; ++i) {
    CHECK(r.nodes[i].id == i);
    CHECK(r.nodes[i].counters.sent[test].messages == local.nodes[i].counters.sent[test].messages);
    CHECK(r.nodes[i].counters.received[test].messages == kRounds * (kNodes - 1));
    CHECK(r.nodes[i].wall_s > 0);
    CHECK(per_node_value[i] == 1000 + i);
  }
  CHECK(r.host.counters.received[std::size_t(MessageType::kNodeDone)].messages == kNodes);
  // Everything between processes went through the transports: node p sent
  // (kNodes - 1) x kRounds to the others, plus its report to the host unless it is on process 0.
  for (std::uint32_t p = 0; p < kNodes; ++p)
    CHECK(transports[p]->sent() == kRounds * (kNodes - 1) + (p == 0 ? 0 : 1) + (p == 0 ? kNodes - 1 : 0));
}

TEST_CASE("transport: a node's own poll that finds its mailbox full keeps each sender's messages in order") {
  // Node 1 sends kCount messages to node 0, whose mailbox holds 4. The
  // transport's other threads deliver the first 4 and stop; node 0's mail checks
  // (has_mail) then take the rest from the transport on its own thread and
  // park them. Node 0 must still receive 0, 1, 2, ... in order.
  constexpr std::uint32_t kCount = 9, kCapacity = 4;
  MachineParams base;
  base.nodes = 2;
  base.mailbox_capacity = kCapacity;
  base.timeout_s = 60;
  Hub hub(2);
  LoopbackTransport t0(hub, 0), t1(hub, 1);
  t0.open_gate(0);  // nothing is delivered to process 0 until all are sent
  std::vector<std::uint32_t> order;
  auto node = [&](NodeContext& ctx) {
    if (ctx.id() == 1) {
      for (std::uint32_t r = 0; r < kCount; ++r) ctx.send(0, MessageType::kTest, Hello{1, r});
    } else {
      t0.exempt_this_thread();
      while (t0.queued() < kCount) std::this_thread::yield();
      t0.open_gate(int(kCapacity));
      while (t0.delivered() < kCapacity) std::this_thread::yield();
      for (int i = 0; i < 64; ++i) (void)ctx.has_mail();  // every 16th looks into the transport, then each one
      t0.open_gate(-1);
      for (std::uint32_t r = 0; r < kCount; ++r) order.push_back(ctx.receive(WaitKind::kIdle).as<Hello>().round);
    }
    ctx.send(kHost, MessageType::kNodeDone, Hello{ctx.id(), 0});
    while (ctx.receive(WaitKind::kIdle).type() != MessageType::kShutdown) {
    }
  };
  std::vector<std::uint32_t> reported;
  std::vector<std::thread> processes;
  for (LoopbackTransport* t : {&t0, &t1})
    processes.emplace_back([&, t] {
      MachineParams mp = base;
      mp.transport = t;
      Machine(mp).run(node, [&](NodeContext& host) { gathering_host(host, reported); });
    });
  for (std::thread& t : processes) t.join();
  std::vector<std::uint32_t> want(kCount);
  for (std::uint32_t r = 0; r < kCount; ++r) want[r] = r;
  CHECK(order == want);
  // Node 0 took packets itself, beyond what the receiving thread was let through.
  CHECK(t0.delivered() >= kCount);
}

TEST_CASE("transport: a machine over a transport needs one node per process") {
  Hub hub(2);
  LoopbackTransport t(hub, 0);
  MachineParams p;
  p.nodes = 3;
  p.transport = &t;
  CHECK_THROWS_WITH_AS(Machine{p}, "the loopback transport runs one node per process: 2 processes, 3 nodes",
                       std::invalid_argument);
}

TEST_CASE("transport: auto work grants are the paper's item in the emulator and half on a transport") {
  MachineParams p;
  CHECK(p.work_grant == WorkGrant::kAuto);
  CHECK(resolved_work_grant(p) == WorkGrant::kItem);
  Hub hub(1);
  LoopbackTransport t(hub, 0);
  p.transport = &t;
  CHECK(resolved_work_grant(p) == WorkGrant::kHalf);
  // A rule given explicitly is kept, with or without a transport.
  for (WorkGrant g : {WorkGrant::kItem, WorkGrant::kNearest, WorkGrant::kHalf}) {
    CAPTURE(work_grant_name(g));
    p.work_grant = g;
    CHECK(resolved_work_grant(p) == g);
    p.transport = nullptr;
    CHECK(resolved_work_grant(p) == g);
    p.transport = &t;
    CHECK(parse_work_grant(work_grant_name(g)) == g);
  }
  CHECK(parse_work_grant("auto") == WorkGrant::kAuto);
  CHECK_THROWS_AS(parse_work_grant("most"), std::invalid_argument);
}

TEST_CASE("transport: a ray to another process's node is refused once its share of the mailbox is taken") {
  // Two processes over the loopback; 8 mailbox slots, so each sender may
  // have 8 / 2 = 4 rays not yet taken by node 1 (MachineState::ray_credits).
  constexpr std::uint32_t kRays = 20;
  MachineParams base;
  base.nodes = 2;
  base.mailbox_capacity = 8;
  base.timeout_s = 60;
  std::atomic<bool> go{false};
  std::atomic<std::uint32_t> before_refusal{0}, refusals{0};
  std::vector<std::uint32_t> order;
  auto node = [&](NodeContext& ctx) {
    if (ctx.id() == 0) {
      std::uint32_t sent = 0;
      while (sent < kRays) {
        if (ctx.try_send(1, MessageType::kRay, Hello{0, sent})) {
          ++sent;
          continue;
        }
        if (refusals++ == 0) {
          before_refusal = sent;
          go = true;  // node 1 starts taking rays only now
        }
        std::this_thread::sleep_for(std::chrono::microseconds(200));
      }
    } else {
      while (!go) std::this_thread::sleep_for(std::chrono::microseconds(200));
      while (order.size() < kRays) {
        const Message m = ctx.receive(WaitKind::kIdle);
        REQUIRE(m.type() == MessageType::kRay);
        order.push_back(m.as<Hello>().round);
      }
    }
    ctx.send(kHost, MessageType::kNodeDone, Hello{ctx.id(), 0});
    while (ctx.receive(WaitKind::kIdle).type() != MessageType::kShutdown) {
    }
  };
  Hub hub(2);
  std::vector<std::unique_ptr<LoopbackTransport>> transports;
  for (std::uint32_t p = 0; p < 2; ++p) transports.push_back(std::make_unique<LoopbackTransport>(hub, p));
  std::vector<std::uint32_t> reported;
  std::vector<std::thread> processes;
  RunReport first;  // process 0's report: every node's counters, gathered
  for (std::uint32_t p = 0; p < 2; ++p)
    processes.emplace_back([&, p] {
      MachineParams mp = base;
      mp.transport = transports[p].get();
      RunReport r = Machine(mp).run(node, [&](NodeContext& host) { gathering_host(host, reported); });
      if (p == 0) first = std::move(r);
    });
  for (std::thread& t : processes) t.join();
  CHECK(before_refusal == 4);  // the window, while node 1 took nothing
  CHECK(refusals > 0);
  std::vector<std::uint32_t> expected(kRays);
  for (std::uint32_t i = 0; i < kRays; ++i) expected[i] = i;
  CHECK(order == expected);  // every ray arrived once, in order, once credits came back
  // Credits go back two at a time (half the window): ten control messages,
  // counted as sent by node 1 and as received by node 0.
  const auto control = std::size_t(MessageType::kControl);
  REQUIRE(first.nodes.size() == 2);
  CHECK(first.nodes[1].counters.sent[control].messages == kRays / 2);
  CHECK(first.nodes[0].counters.received[control].messages == kRays / 2);
  CHECK(first.nodes[0].counters.received[control].bytes == kRays / 2 * sizeof(std::int32_t));
}
