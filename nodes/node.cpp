#include "nodes/node.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <thread>

#include "nodes/cpu_time.h"
#include "nodes/machine.h"

namespace raynode::nodes {

MessageCounts NodeCounters::total_sent() const {
  MessageCounts t;
  for (const MessageCounts& c : sent) t.messages += c.messages, t.bytes += c.bytes;
  return t;
}

MessageCounts NodeCounters::total_received() const {
  MessageCounts t;
  for (const MessageCounts& c : received) t.messages += c.messages, t.bytes += c.bytes;
  return t;
}

NodeCounters& NodeCounters::operator+=(const NodeCounters& o) {
  for (std::size_t i = 0; i < kMessageTypeCount; ++i) {
    sent[i].messages += o.sent[i].messages;
    sent[i].bytes += o.sent[i].bytes;
    received[i].messages += o.received[i].messages;
    received[i].bytes += o.received[i].bytes;
  }
  busy_s += o.busy_s;
  idle_s += o.idle_s;
  communication_s += o.communication_s;
  overhead_cpu_s += o.overhead_cpu_s;
  full_mailbox_retries += o.full_mailbox_retries;
  mail_checks += o.mail_checks;
  services += o.services;
  service_wait_s += o.service_wait_s;
  link_waits += o.link_waits;
  link_wait_s += o.link_wait_s;
  idle_wall_s += o.idle_wall_s;
  communication_wall_s += o.communication_wall_s;
  backlog_peak = std::max(backlog_peak, o.backlog_peak);
  return *this;
}

NodeContext::NodeContext(MachineState& machine, NodeId id, std::size_t budget, std::uint32_t mailbox_capacity,
                         std::uint32_t max_payload)
    : machine_(&machine),
      transport_(machine.params.transport),
      id_(id),
      arena_(id, budget),
      mailbox_(std::make_unique<Mailbox>(arena_, mailbox_capacity, max_payload)),
      receive_buffer_(arena_, max_payload, "its receive buffer"),
      backlog_(&arena_),
      deferred_(&arena_),
      backlog_current_(&arena_),
      ray_taken_(&arena_),
      model_clock_(machine.params.clock == ComputeClock::kModel),
      work_price_(applied_corun_slowdown(machine.params)),
      poll_cost_(id_ != kHost ? applied_poll_s(machine.params) : 0.0) {
  // A node's count of rays taken per sender, from its arena before any mode
  // sizes its buffers from what is left (return_ray_credit).
  if (transport_ && id_ != kHost) ray_taken_.assign(std::size_t(machine.params.nodes) + 1, 0);
}

NodeContext::~NodeContext() {
  backlog_.clear();
  deferred_.clear();
  backlog_current_ = std::pmr::vector<std::byte>(&arena_);
  ray_taken_ = std::pmr::vector<std::int32_t>(&arena_);
}

std::uint32_t NodeContext::node_count() const { return machine_->params.nodes; }
const Topology& NodeContext::topology() const { return machine_->topology; }
const NetworkModel& NodeContext::network() const { return machine_->params.network; }
WorkRequestRoute NodeContext::work_request_route() const { return machine_->params.work_request_route; }
WorkGrant NodeContext::work_grant() const { return machine_->params.work_grant; }

void NodeContext::sync_compute() {
  if (id_ == kHost) return;  // the host is outside the emulated machine: its bookkeeping takes no virtual time
  if (model_clock_) {
    if (!meter_) return;
    const double work = meter_(meter_state_);
    const double d = work_price_ * std::max(0.0, work - cpu_mark_);
    clock_ += d;
    counters_.busy_s += d;
    cpu_mark_ = work;
    return;
  }
  const double cpu = thread_cpu_seconds();
  const double d = std::max(0.0, cpu - cpu_mark_);
  clock_ += d;
  counters_.busy_s += d;
  cpu_mark_ = cpu;
}

void NodeContext::end_messaging() {
  if (id_ == kHost || model_clock_) return;  // the model clock never reads the CPU clock
  const double cpu = thread_cpu_seconds();
  counters_.overhead_cpu_s += std::max(0.0, cpu - cpu_mark_);
  cpu_mark_ = cpu;
}

double NodeContext::now() {
  sync_compute();
  return clock_;
}

void NodeContext::charge(double seconds) {
  sync_compute();
  clock_ += seconds;
  counters_.busy_s += seconds;
}

double NodeContext::serve_interrupt(double arrival, double seconds) {
  ++counters_.services;
  if (!(seconds > 0)) return arrival;  // a free service (--network none) occupies no handler time
  const double start = handler_busy_.take(arrival, seconds);  // the first gap at or after the arrival
  counters_.service_wait_s += start - arrival;
  charge(seconds);
  return start + seconds;
}

void NodeContext::note_wait(WaitReason reason, std::int64_t a, std::int64_t b) {
  wait_a_.store(a, std::memory_order_relaxed);
  wait_b_.store(b, std::memory_order_relaxed);
  clock_seen_.store(clock_, std::memory_order_relaxed);
  wait_reason_.store(std::uint8_t(reason), std::memory_order_relaxed);
}

std::string NodeContext::describe_wait() const {
  const std::int64_t a = wait_a_.load(std::memory_order_relaxed), b = wait_b_.load(std::memory_order_relaxed);
  std::string what;
  switch (WaitReason(wait_reason_.load(std::memory_order_relaxed))) {
    case WaitReason::kNone: what = "computing (or between waits)"; break;
    case WaitReason::kMail: what = "waiting for mail"; break;
    case WaitReason::kPermit: what = "waiting for a run permit"; break;
    case WaitReason::kMailboxRoom: what = fmt::format("waiting for room in {}'s full mailbox", node_name(NodeId(a))); break;
    case WaitReason::kWorkGrant: what = "waiting for the answer to its work request"; break;
    case WaitReason::kPage: what = fmt::format("waiting for page {} from {}", a, node_name(NodeId(b))); break;
    case WaitReason::kDone: what = "finished"; break;
  }
  return fmt::format("{}: {} (clock {:.6g} s, {} messages parked)", node_name(id_), what,
                     clock_seen_.load(std::memory_order_relaxed), backlog_size_.load(std::memory_order_relaxed));
}

bool NodeContext::try_run() {
  Scheduler& s = *machine_->scheduler;
  if (id_ == kHost || !s.enabled()) return true;
  // Fast path without reading the CPU clock: the permit is held (or was
  // granted while we waited).
  const bool ok = s.granted_flag(id_).load(std::memory_order_acquire) || s.try_run(id_, now());
  fresh_grant_ = ok && want_permit_;
  want_permit_ = !ok;
  return ok;
}

bool NodeContext::try_resume() {
  Scheduler& s = *machine_->scheduler;
  fresh_grant_ = false;  // resumed inside a work unit: its next yield_point checks as usual
  if (id_ == kHost || !s.enabled() || s.granted_flag(id_).load(std::memory_order_acquire)) return true;
  const bool ok = s.try_run(id_, now(), true);
  want_permit_ = !ok;
  return ok;
}

bool NodeContext::yield_point() {
  if (id_ == kHost || !machine_->scheduler->enabled()) return true;
  // A permit just granted after a refusal runs one work unit first: the
  // node's clock was within the window at the grant, and what it has
  // gained since is the CPU time of asking for the permit. Checked again
  // here, that time alone took it past a queued node at the window's edge
  // (--schedule-window 0 under the CPU clock: a permit went round the
  // queue with no work done, every hand-over adding a microsecond to a
  // clock, and the run never ended).
  if (fresh_grant_) {
    fresh_grant_ = false;
    return true;
  }
  const bool ok = machine_->scheduler->yield_point(id_, now());
  want_permit_ = !ok;
  return ok;
}

void NodeContext::release_run() {
  if (id_ != kHost) machine_->scheduler->release(id_);
}

void NodeContext::await_reply(Awaited what) {
  if (id_ != kHost && machine_->scheduler->enabled()) machine_->scheduler->await_reply(id_, now(), what);
}

bool NodeContext::peer_reads_mail(NodeId peer) const {
  const Scheduler& s = *machine_->scheduler;
  if (peer == kHost || !s.scheduled_mail()) return true;
  return s.granted_flag(peer).load(std::memory_order_relaxed) || s.serving_flag(peer).load(std::memory_order_relaxed);
}

void NodeContext::wait_for_mail(double timeout_s) {
  check_stop();
  if (!backlog_.empty()) return;
  sync_compute();
  const bool generic = wait_reason_.load(std::memory_order_relaxed) == std::uint8_t(WaitReason::kNone);
  const bool for_permit = want_permit_ && id_ != kHost && !machine_->scheduler->granted_flag(id_).load(std::memory_order_relaxed);
  if (generic) note_wait(for_permit ? WaitReason::kPermit : WaitReason::kMail);
  // Real time blocked: waiting for a page or a work grant is communication, anything else idle.
  const auto wall0 = std::chrono::steady_clock::now();
  const auto reason = WaitReason(wait_reason_.load(std::memory_order_relaxed));
  struct BookWall {
    double& to;
    std::chrono::steady_clock::time_point from;
    ~BookWall() { to += std::chrono::duration<double>(std::chrono::steady_clock::now() - from).count(); }
  } book{reason == WaitReason::kPage || reason == WaitReason::kWorkGrant ? counters_.communication_wall_s
                                                                         : counters_.idle_wall_s,
         wall0};
  if (id_ == kHost) {
    // The host waits quietly: senders do not wake it per message (a pixel
    // block every few microseconds would take a core from a node each
    // time). It looks again after a nap of kHostNapMinS to kHostNapMaxS
    // (next_host_nap).
    mailbox_->wait_quietly(machine_->stop, timeout_s > 0 ? std::min(timeout_s, host_nap_s_) : host_nap_s_);
    host_nap_s_ = next_host_nap(host_nap_s_, mailbox_->claimed(), mailbox_->capacity(), host_gathering_);
  } else if (Scheduler& s = *machine_->scheduler;
             s.scheduled_mail() && !s.granted_flag(id_).load(std::memory_order_relaxed)) {
    // Mail is served with a service permit (scheduler.h): give ours back,
    // then look at the mailbox. The fence pairs with the one a sender makes
    // between publishing its message and reading our flags (push_to): either
    // it sees that we hold no permit and asks the scheduler to serve us, or
    // we see its message here and ask ourselves.
    if (s.serving_flag(id_).load(std::memory_order_relaxed)) s.end_service(id_);
    std::atomic_thread_fence(std::memory_order_seq_cst);
    if (mailbox_->has_message()) s.note_mail(id_);
    mailbox_->wait_for_flags(machine_->stop, timeout_s, s.granted_flag(id_), s.serving_flag(id_));
  } else if (Transport* t = machine_->params.transport) {
    // Mail from other processes: the transport looks for it at once while we wait.
    t->note_waiting(+1);
    struct Done {
      Transport* t;
      ~Done() { t->note_waiting(-1); }
    } done{t};
    mailbox_->wait(machine_->stop, timeout_s, &s.granted_flag(id_));
  } else {
    mailbox_->wait(machine_->stop, timeout_s, &s.granted_flag(id_));
  }
  if (generic) note_wait(WaitReason::kNone);
  end_messaging();
}

double next_host_nap(double nap_s, std::uint32_t queued, std::uint32_t capacity, bool gathering) {
  if (queued == 0 || (gathering && queued < capacity / 16)) return std::min(2 * nap_s, kHostNapMaxS);
  if (!gathering || queued >= capacity / 4) return kHostNapMinS;
  return nap_s;
}

void NodeContext::mark_work_done() { work_done_s_ = now(); }

void NodeContext::reset_cpu_mark() {
  // Metered work is all the node's own (nothing of the emulator is in it):
  // never dropped.
  if (!model_clock_) cpu_mark_ = thread_cpu_seconds();
}

void NodeContext::set_work_meter(WorkMeter meter, const void* state) {
  sync_compute();
  meter_ = meter;
  meter_state_ = state;
  if (model_clock_) cpu_mark_ = meter_ ? meter_(meter_state_) : 0.0;
}

ComputeClock NodeContext::compute_clock() const { return machine_->params.clock; }

void NodeContext::check_stop() const {
  if (machine_->stop.load(std::memory_order_acquire)) throw RunAborted();
}

bool NodeContext::push_to(NodeId dest, MessageHeader& header, std::span<const std::span<const std::byte>> parts,
                          bool& costly) {
  if (dest != kHost && dest >= machine_->params.nodes)
    throw std::logic_error(fmt::format("{} sent a {} message to node {}, but the machine has {} nodes",
                                       node_name(id_), message_type_name(header.type), dest,
                                       machine_->params.nodes));
  if (!machine_->is_local(dest)) {
    // Another process's participant (transport.h): the transport never
    // refuses, and the send is the engine's work, not the node's.
    header.payload_bytes = 0;
    for (const auto& p : parts) header.payload_bytes += std::uint32_t(p.size());
    if (header.payload_bytes > machine_->params.max_payload)  // as the receiver's mailbox would refuse it
      throw std::length_error(fmt::format("{} message of {} B exceeds the mailbox slot of {} B",
                                          message_type_name(header.type), header.payload_bytes,
                                          machine_->params.max_payload));
    // A ray to another process's node needs a credit: without one, its
    // share of the node's mailbox is full (MachineState::ray_credits).
    if (header.type == MessageType::kRay && dest != kHost) {
      std::atomic<std::int32_t>& credit = machine_->ray_credit(id_, dest);
      if (credit.load(std::memory_order_acquire) <= 0) {
        costly = false;
        return false;
      }
      credit.fetch_sub(1, std::memory_order_relaxed);  // only this participant takes its credits
    }
    machine_->params.transport->send(dest, header, parts, machine_->params.nodes);
    costly = true;
    return true;
  }
  if (dest != kHost && machine_->finished[dest].load(std::memory_order_acquire))
    throw std::logic_error(fmt::format("{} sent a {} message to node {}, which has finished", node_name(id_),
                                       message_type_name(header.type), dest));
  Scheduler& s = *machine_->scheduler;
  bool crowded = false;
  costly = false;
  if (!machine_->context(dest).mailbox().try_push(header, parts, s.scheduled_mail() ? &crowded : nullptr, &costly))
    return false;
  // try_push ended with a seq_cst fence after publishing: the flags are read
  // after it (see wait_for_mail). A mailbox half full is served at once (one
  // permit more than K if need be), as the interrupt it would be on a real
  // node, before senders find it full (dataflow then spills rays).
  if (dest != kHost && s.scheduled_mail() && !s.granted_flag(dest).load(std::memory_order_relaxed) &&
      !s.serving_flag(dest).load(std::memory_order_relaxed)) {
    s.note_mail(dest, crowded);
    costly = true;
  }
  return true;
}

bool NodeContext::try_send(NodeId dest, MessageType type, std::span<const std::span<const std::byte>> parts,
                           double depart, std::uint32_t wire_bytes) {
  // The clock is read only when the stamp needs it (no `depart` given):
  // under the CPU clock each reading is a system call. Skipping it loses
  // nothing; the time is counted at the node's next synchronisation.
  const bool stamp_now = depart < 0;
  if (stamp_now) sync_compute();
  check_stop();
  MessageHeader h;
  h.type = type;
  h.source = id_;
  std::size_t bytes = 0;
  for (const auto& p : parts) bytes += p.size();
  h.wire_bytes = wire_bytes ? wire_bytes : std::uint32_t(bytes);
  // A node's own send (not an interrupt-level reply, whose handler time
  // includes it) first spends the message software's CPU time.
  const NetworkModel& net = network();
  const double overhead = depart < 0 && !is_host() ? net.send_overhead_s : 0.0;
  h.send_time = (depart >= 0 ? depart : clock_) + overhead;
  const std::uint32_t hops = topology().hops(id_, dest);
  // Under link contention the message streams through its route once every
  // link of it is free (links.h); else it never waits for a link.
  const bool contended = machine_->links && !is_host() && dest != kHost && hops > 0;
  // A destination that looks full refuses the message before any link is
  // reserved (dataflow tries full mailboxes often; a reservation would be
  // cancelled at once).
  if (contended && machine_->context(dest).mailbox().looks_full()) {
    if (!stamp_now) sync_compute();
    end_messaging();
    return false;
  }
  double ready = 0, entered = 0, hold = 0;
  if (contended) {
    hold = double(h.wire_bytes) * net.per_byte_s + double(hops) * net.per_hop_s;
    ready = h.send_time + net.latency_s;
    entered = machine_->links->reserve(id_, dest, ready, hold);
    h.arrival_time = entered + hold;
  } else {
    h.arrival_time = h.send_time + net.message_time(h.wire_bytes, hops);
  }
  bool costly = false;
  const bool ok = push_to(dest, h, parts, costly);
  if (ok) {
    machine_->progress.fetch_add(1, std::memory_order_relaxed);
    MessageCounts& c = counters_.sent[std::size_t(type)];
    ++c.messages;
    c.bytes += h.wire_bytes;
    // The message software's time, after the stamp's clock reading (charge()
    // would read the CPU clock again: a system call per message).
    clock_ += overhead;
    counters_.busy_s += overhead;
    if (entered > ready) {
      ++counters_.link_waits;
      counters_.link_wait_s += entered - ready;
    }
  } else if (contended) {
    machine_->links->cancel(id_, dest, entered, hold);  // not sent: the links were never used
  }
  // A plain copy into the mailbox (~0.1 µs) is left to the node's computing,
  // as a real node's send overhead: reading the CPU clock to exclude it
  // would cost more than it excludes. A wake-up, a call into the scheduler
  // or a full mailbox is the emulator's and is excluded.
  if (costly || !ok) {
    if (!stamp_now) sync_compute();  // the computing before the send is the node's, not the emulator's
    end_messaging();
  }
  return ok;
}

void NodeContext::send(NodeId dest, MessageType type, std::span<const std::span<const std::byte>> parts,
                       double depart, std::uint32_t wire_bytes) {
  if (try_send(dest, type, parts, depart, wire_bytes)) return;
  // The destination is full: wait for room, parking our own incoming mail
  // so that whoever fills our mailbox can go on (no cycle of full mailboxes
  // can block everyone). Parked messages live in our arena.
  MessageHeader h;
  int spins = 0;
  const bool generic = wait_reason_.load(std::memory_order_relaxed) == std::uint8_t(WaitReason::kNone);
  if (generic) note_wait(WaitReason::kMailboxRoom, dest);
  struct Clear {
    NodeContext* self;
    bool on;
    ~Clear() {
      if (on) self->note_wait(WaitReason::kNone);
    }
  } clear{this, generic};
  // Its owner may sleep without a permit while every permit is held by a
  // sender blocked like us: have the scheduler wake it now.
  Scheduler& sched = *machine_->scheduler;
  while (true) {
    if (dest != kHost && sched.scheduled_mail()) sched.note_mail(dest, true);
    ++counters_.full_mailbox_retries;
    while (backlog_.size() < park_limit_ && mailbox_->try_pop(h, receive_buffer_.data())) {
      backlog_.push_back(Parked{h, std::pmr::vector<std::byte>(receive_buffer_.data(),
                                                               receive_buffer_.data() + h.payload_bytes, &arena_)});
      counters_.backlog_peak = std::max<std::uint64_t>(counters_.backlog_peak, backlog_.size());
      backlog_size_.store(backlog_.size(), std::memory_order_relaxed);
    }
    if (++spins < 64) std::this_thread::yield();
    else std::this_thread::sleep_for(std::chrono::microseconds(50));
    if (try_send(dest, type, parts, depart, wire_bytes)) return;
  }
}

Message NodeContext::take(const MessageHeader& h, std::span<const std::byte> payload) {
  MessageCounts& c = counters_.received[std::size_t(h.type)];
  ++c.messages;
  c.bytes += h.wire_bytes;
  if (h.type == MessageType::kRay && transport_ && id_ != kHost && !machine_->is_local(h.source)) return_ray_credit(h.source);
  return Message{h, payload};
}

void NodeContext::return_ray_credit(NodeId source) {
  // Credits go back in batches of half the window (at least one), so that
  // a stream of rays costs one credit message per half window.
  std::int32_t& taken = ray_taken_[source == kHost ? machine_->params.nodes : source];
  if (++taken < std::max<std::int32_t>(1, machine_->ray_window / 2)) return;
  MessageHeader h;
  h.type = MessageType::kControl;
  h.reserved = kRayCreditTag;
  h.source = id_;
  h.payload_bytes = sizeof(std::int32_t);
  h.wire_bytes = sizeof(std::int32_t);
  const std::span<const std::byte> parts[1] = {std::as_bytes(std::span(&taken, 1))};
  transport_->send(source, h, parts, machine_->params.nodes);
  MessageCounts& c = counters_.sent[std::size_t(MessageType::kControl)];
  ++c.messages;
  c.bytes += h.wire_bytes;
  taken = 0;
}

void NodeContext::accept(const MessageHeader& header, std::span<const std::byte> payload) {
  const std::span<const std::byte> parts[1] = {payload};
  if (mailbox_->try_push(header, parts)) return;
  // Full: what the mailbox holds came first (from this sender too, pushed by
  // the transport's receiving thread), and poll() serves the backlog before
  // the mailbox, so it moves to the backlog ahead of this message: each
  // sender's messages stay in order. Popped through a scratch buffer: the
  // receive buffer may hold the message the owner is handling (has_mail()).
  thread_local std::vector<std::byte> scratch;
  scratch.resize(receive_buffer_.size());
  MessageHeader h;
  while (mailbox_->try_pop(h, scratch.data()))
    backlog_.push_back(Parked{h, std::pmr::vector<std::byte>(scratch.data(), scratch.data() + h.payload_bytes, &arena_)});
  h = header;
  h.payload_bytes = std::uint32_t(payload.size());
  backlog_.push_back(Parked{h, std::pmr::vector<std::byte>(payload.begin(), payload.end(), &arena_)});
  counters_.backlog_peak = std::max<std::uint64_t>(counters_.backlog_peak, backlog_.size());
  backlog_size_.store(backlog_.size(), std::memory_order_relaxed);
}

bool NodeContext::poll(Message& out) {
  check_stop();
  ++counters_.mail_checks;
  // The described machine's look for mail; added without reading the clock,
  // which sums what it is charged in any order.
  clock_ += poll_cost_;
  counters_.busy_s += poll_cost_;
  // Nothing to take: no clock reading (under the CPU clock each is a
  // system call, ~0.6 µs here, against ~10 µs of work per work item); the
  // look itself, one atomic load, counts as the node's computing, as a
  // real node's mailbox check would.
  if (backlog_.empty() && !mailbox_->has_message()) {
    // Under a transport, take what waits in the other processes' messages
    // first (one probe), rather than leave it to the receiving thread.
    if (!transport_ || !transport_->poll() || (backlog_.empty() && !mailbox_->has_message())) return false;
  }
  sync_compute();
  bool got = false;
  if (!backlog_.empty()) {
    Parked p = std::move(backlog_.front());
    backlog_.pop_front();
    backlog_size_.store(backlog_.size(), std::memory_order_relaxed);
    backlog_current_ = std::move(p.payload);
    out = p.counted ? Message{p.header, backlog_current_} : take(p.header, backlog_current_);
    got = true;
  } else {
    MessageHeader h;
    if (mailbox_->try_pop(h, receive_buffer_.data())) {
      out = take(h, std::span<const std::byte>(receive_buffer_.data(), h.payload_bytes));
      got = true;
    }
  }
  end_messaging();
  return got;
}

void NodeContext::defer(const Message& m) {
  deferred_.push_back(
      Parked{m.header, std::pmr::vector<std::byte>(m.payload.begin(), m.payload.end(), &arena_), true});
  counters_.backlog_peak = std::max<std::uint64_t>(counters_.backlog_peak, backlog_.size() + deferred_.size());
}

void NodeContext::resume_deferred() {
  while (!deferred_.empty()) {
    backlog_.push_front(std::move(deferred_.back()));
    deferred_.pop_back();
  }
  backlog_size_.store(backlog_.size(), std::memory_order_relaxed);
}

void NodeContext::advance_to(double t, WaitKind kind) {
  if (t <= clock_) return;
  (kind == WaitKind::kIdle ? counters_.idle_s : counters_.communication_s) += t - clock_;
  clock_ = t;
}

Message NodeContext::receive(WaitKind kind) {
  Message m;
  bool released = false;
  while (!poll(m)) {
    if (!released) {
      release_run();  // blocked: let a waiting node compute
      released = true;
    }
    wait_for_mail(0);  // released, so no permit can arrive: only mail or a stop ends it
  }
  if (m.header.arrival_time > clock_) {
    const double gap = m.header.arrival_time - clock_;
    clock_ = m.header.arrival_time;
    (kind == WaitKind::kIdle ? counters_.idle_s : counters_.communication_s) += gap;
  }
  return m;
}

}  // namespace raynode::nodes
