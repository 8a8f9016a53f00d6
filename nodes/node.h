// A node's whole world: its id, arena, mailbox, virtual clock, counters and
// the topology (docs/architecture.md, "The node emulator"; CONVENTIONS: "node code
// reaches its world only through its node context").
//
// Place in the data flow: Machine::run creates one NodeContext per node (and
// one for the host), hands it to the node's main function on the node's
// thread; node code sends and receives through it and allocates from its
// arena.
//
// Virtual time. The clock advances by the thread's own CPU time while node
// code computes (sampled at each messaging call) — or, under the model
// clock (--clock model, MachineParams::clock), by the growth of the node's
// work meter (set_work_meter: the cost model of the rays it traced,
// core/cost_model.h) — by explicit charges
// (charge()), and by waiting: a blocking receive sets clock = max(clock,
// arrival) and books the gap as idle or communication time. CPU time spent
// inside the messaging layer itself is *not* added to the clock (the network
// model's latency stands for the real machine's message software); it is
// reported as `overhead_cpu_s`. Handlers that serve a message at interrupt
// level (a page request, a work request) use the message's arrival time:
// serve_interrupt() queues it behind the handler's previous service, charges
// the service cost to the serving node, and gives the reply's departure
// (arrival, or the end of the service before, plus the service cost); the
// reply is sent with that departure without moving the clock.
//
// Thread safety: a NodeContext belongs to its node's thread; only the
// machine-wide stop and the peers' mailboxes are touched by other threads.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <cstddef>
#include <deque>
#include <memory>
#include <memory_resource>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "nodes/arena.h"
#include "nodes/mailbox.h"
#include "nodes/message.h"
#include "nodes/network.h"
#include "nodes/scheduler.h"
#include "nodes/timeline.h"
#include "nodes/topology.h"
#include "nodes/transport.h"

namespace raynode::nodes {

/// Where an idle node sends a work request (work.h): kRing, the paper's
/// rule, to its ring successor; kLastGrantor first straight to the node that
/// granted its last work item (likely still busy), and on to the ring from
/// the requester's successor if that node has none left. kOff sends none:
/// a node whose submap is rendered is done (static submaps only, the
/// baseline the requests' gain is measured against; which node renders
/// which pixel, and so every svm page count, no longer depends on the
/// host's thread scheduling).
enum class WorkRequestRoute : std::uint8_t { kRing, kLastGrantor, kOff };

/// What a busy node grants a work request (work.h): kItem, the paper's rule,
/// one work item from the far end of its submap; kHalf the far half of its
/// remaining item rows (within one row, half of its items) as one
/// rectangle, which the requester renders as its new submap and may in
/// turn grant from. kHalf keeps a requester's pixels together, so the pages
/// it fetches serve many of them (svm), and needs fewer requests. kNearest
/// grants one item, as kItem, but the one nearest the requester's last
/// item (the request carries its centre): a requester's items lie next to
/// each other and to its own submap, so its cached pages serve them.
/// kAuto is the machine's choice (resolved_work_grant, machine.h): kItem in
/// the emulator, kHalf on a transport's processes, where every grant is a
/// real round trip whose wait depends on how often the granting node takes
/// its mail.
enum class WorkGrant : std::uint8_t { kItem, kHalf, kNearest, kAuto };

/// Thrown inside node code when the run is being stopped because another
/// participant failed (or the watchdog fired); Machine::run swallows it.
class RunAborted : public std::runtime_error {
 public:
  RunAborted() : std::runtime_error("run aborted") {}
};

/// What advances a node's clock while it computes.
enum class ComputeClock {
  kCpu,    ///< the thread's own CPU time (CLOCK_THREAD_CPUTIME_ID), as docs/architecture.md states
  kModel,  ///< a cost model of the work done (operation counts x calibrated unit costs,
           ///< core/cost_model.h): deterministic, and blind to the host's cache refills
           ///< and thread switches
};

/// How a blocking receive books the time it waits.
enum class WaitKind {
  kIdle,           ///< nothing to do (waiting for work or for the end)
  kCommunication,  ///< waiting for data needed to go on (e.g. a page)
};

/// What a node is blocked on, for the watchdog's report (Machine::run).
enum class WaitReason : std::uint8_t {
  kNone,         ///< computing (or between waits)
  kMail,         ///< any message
  kPermit,       ///< a run permit from the virtual-time scheduler
  kMailboxRoom,  ///< room in node `a`'s full mailbox
  kWorkGrant,    ///< the answer to its work request
  kPage,         ///< page `a` from its home node `b`
  kDone,         ///< its main function returned
};

/// Per-type message counters.
struct MessageCounts {
  std::uint64_t messages = 0;
  std::uint64_t bytes = 0;  ///< wire bytes
};

/// A node's counters (virtual seconds, messages, memory).
struct NodeCounters {
  std::array<MessageCounts, kMessageTypeCount> sent{};
  std::array<MessageCounts, kMessageTypeCount> received{};
  double busy_s = 0;           ///< computing: own CPU time plus charges
  double idle_s = 0;           ///< blocked with nothing to do
  double communication_s = 0;  ///< blocked waiting for data
  double overhead_cpu_s = 0;   ///< CPU time in the emulator's messaging code (not in the clock)
  std::uint64_t full_mailbox_retries = 0;  ///< send() attempts that found the destination full
  std::uint64_t mail_checks = 0;  ///< poll() calls: looks for mail, found or not
  std::uint64_t services = 0;  ///< messages served at interrupt level (serve_interrupt)
  double service_wait_s = 0;   ///< virtual seconds those messages waited for the handler (a busy home node)
  std::uint64_t link_waits = 0;  ///< messages sent that waited for a link held by another (link contention)
  double link_wait_s = 0;        ///< virtual seconds they waited
  std::uint64_t backlog_peak = 0;          ///< most messages parked while a send waited
  /// Real (wall) seconds blocked for mail: for a page or a work grant
  /// (communication), for anything else (idle). Under a transport, with
  /// NodeReport::wall_s, what a rank really did: busy = wall - both.
  double idle_wall_s = 0, communication_wall_s = 0;

  MessageCounts total_sent() const;
  MessageCounts total_received() const;
  NodeCounters& operator+=(const NodeCounters& o);
};

class MachineState;  // machine.h: what all participants share

/// The host's nap between looks at its mailbox (NodeContext::wait_for_mail),
/// seconds.
inline constexpr double kHostNapMinS = 100e-6, kHostNapMaxS = 2e-3;

/// The host's next nap after one that ended with `queued` of its mailbox's
/// `capacity` slots filled, seconds. An empty mailbox doubles it, up to
/// kHostNapMaxS. Mail waiting: a host that answers (`gathering` false)
/// looks again after kHostNapMinS; a gathering host doubles its nap while
/// fewer than capacity/16 messages wait, keeps it below capacity/4 and
/// drops to kHostNapMinS from there. A steady stream of pixel messages
/// then wakes the gathering host a few hundred times a second, tens of
/// messages a look, instead of every kHostNapMinS: a wake-up on a core
/// where a node computes costs that node CPU time (its caches), which its
/// virtual clock counts.
double next_host_nap(double nap_s, std::uint32_t queued, std::uint32_t capacity, bool gathering);

class NodeContext {
 public:
  /// Built by Machine. `mailbox_capacity` slots of `max_payload` bytes are
  /// taken from `budget` (the host's budget is unbounded).
  NodeContext(MachineState& machine, NodeId id, std::size_t budget, std::uint32_t mailbox_capacity,
              std::uint32_t max_payload);
  NodeContext(const NodeContext&) = delete;
  NodeContext& operator=(const NodeContext&) = delete;
  ~NodeContext();

  NodeId id() const { return id_; }
  bool is_host() const { return id_ == kHost; }
  std::uint32_t node_count() const;
  const Topology& topology() const;
  const NetworkModel& network() const;
  /// Where an idle node sends its next work request (MachineParams).
  WorkRequestRoute work_request_route() const;
  /// What a busy node grants a work request (MachineParams).
  WorkGrant work_grant() const;
  Arena& arena() { return arena_; }
  /// The transport to other processes (MachineParams::transport); null in the emulator.
  Transport* transport() const { return transport_; }
  Mailbox& mailbox() { return *mailbox_; }
  const NodeCounters& counters() const { return counters_; }

  // --- Virtual time -----------------------------------------------------
  /// The clock in virtual seconds, after adding the CPU time computed since
  /// the last sample.
  double now();
  /// The clock as of its last synchronisation (now(), a send, a receive),
  /// without reading the CPU clock: up to the CPU time computed since.
  double last_synced_clock() const { return clock_; }
  /// Adds a modelled cost (e.g. serving a request) as busy time.
  void charge(double seconds);
  /// Serves a message that arrived at `arrival` at interrupt level for
  /// `seconds` (virtual): the node's one interrupt handler serves one
  /// message at a time, so a message that arrives while another is served
  /// waits (queueing at a busy home node). Each service takes the first gap
  /// of the handler's timeline, at or after its arrival, long enough for it:
  /// the node takes messages in real-time order, which need not be their
  /// arrival order in virtual time. Charges `seconds` as busy time and
  /// returns when the service ends: the departure time of its reply.
  double serve_interrupt(double arrival, double seconds);
  /// Records now() as the end of this node's work (the farm calls it when
  /// its work request returns); the run's parallel time is the largest
  /// such time (or final clock, for nodes that never mark it).
  void mark_work_done();
  double work_done_time() const { return work_done_s_; }
  /// Starts measuring from here: drops CPU time since the last sample (used
  /// after a load phase, or a wait, that is not the node's work). No effect
  /// under the model clock: metered work is never dropped.
  void reset_cpu_mark();
  /// The modelled compute seconds of this node's work so far: `meter(state)`
  /// must be cheap and never decrease. Under ComputeClock::kModel the clock
  /// advances by its growth at every sample (a node without a meter then
  /// computes for free); under kCpu it is ignored. Measuring starts at the
  /// call. Owner thread only; `state` must outlive the node's main.
  using WorkMeter = double (*)(const void* state);
  void set_work_meter(WorkMeter meter, const void* state);
  ComputeClock compute_clock() const;

  // --- What the node waits for (the watchdog's report) -------------------
  /// Records what the node is about to block on (`a`, `b`: the reason's
  /// operands, see WaitReason); kNone when the wait is over. Generic waits
  /// (wait_for_mail, a blocked send) record themselves when nothing more
  /// specific is set. Owner thread writes, the watchdog reads (relaxed).
  void note_wait(WaitReason reason, std::int64_t a = -1, std::int64_t b = -1);
  /// One line: "waiting for page 12 from node 3 (clock 0.0123 s)".
  std::string describe_wait() const;

  // --- Virtual-time scheduling (scheduler.h) ------------------------------
  /// May this node compute now? Takes a run permit if one is free; else the
  /// node is queued and the caller should wait_for_mail() (which also ends
  /// when the permit arrives) and ask again.
  bool try_run();
  /// try_run() for a node resuming inside a work unit after awaiting a
  /// reply (scheduler.h: it gets the next free permit whatever its clock).
  bool try_resume();
  /// Between work units: false if the permit went to a node lagging behind
  /// in virtual time (then wait_for_mail() and try_run() again). The first
  /// call after try_run() got the permit following a refusal passes: a
  /// grantee runs at least one work unit (no permit goes round the queue
  /// with no work done).
  bool yield_point();
  /// Gives up the run permit (receive() does so itself before blocking).
  void release_run();
  /// Gives up the run permit to block for the reply to this node's own
  /// request (a page; Awaited::kWork: a work grant or its request's
  /// return): until it runs again its clock holds the others back
  /// (scheduler.h). The caller must keep serving its mail while it waits.
  void await_reply(Awaited what = Awaited::kReply);
  /// Can `peer` read its mail without first getting a permit? False only
  /// under scheduled mail wake-ups (scheduler.h) while `peer` holds no
  /// permit: its reply to this node then waits for a free permit, and a
  /// node that waits for that reply holding its own permit (spinning on
  /// it) only delays it. Relaxed reads: a hint, as the peer's state may
  /// change at once.
  bool peer_reads_mail(NodeId peer) const;
  /// Bounds how many incoming messages a blocked send() parks in the arena
  /// (default: no bound). Only for a node whose blocking sends all go to
  /// a consumer that never blocks on it (dataflow: only to the host): a
  /// node that stops parking leaves its mailbox full, so its senders must
  /// not wait for it.
  void set_park_limit(std::size_t messages) { park_limit_ = messages; }
  /// Host only: the host only gathers (pixels, done messages) and answers
  /// nothing a node waits for, so its mail may queue up between its looks
  /// (next_host_nap). Off by default: the host looks again soon after any
  /// message (dataflow's host runs termination waves).
  void set_host_gathering(bool on) { host_gathering_ = on; }

  // --- Sending ------------------------------------------------------------
  /// Sends `parts` (concatenated) to `dest` as a message of `type`. Departs
  /// at now(), or at `depart` when >= 0 (interrupt-level replies). Blocks
  /// while the destination mailbox is full, parking this node's own incoming
  /// messages meanwhile so that two nodes sending to each other cannot
  /// deadlock (at most set_park_limit() of them; the rest stay in the
  /// mailbox). Throws RunAborted, std::length_error (payload too big),
  /// std::logic_error (dest out of range or finished), ArenaExhausted when
  /// the parked messages outgrow the arena.
  void send(NodeId dest, MessageType type, std::span<const std::span<const std::byte>> parts, double depart = -1,
            std::uint32_t wire_bytes = 0);
  /// As send, but returns false (nothing sent, nothing counted) when the
  /// destination mailbox is full.
  bool try_send(NodeId dest, MessageType type, std::span<const std::span<const std::byte>> parts,
                double depart = -1, std::uint32_t wire_bytes = 0);

  /// Typed conveniences: the payload is `msg`'s bytes, then `tail`.
  template <class M>
  void send(NodeId dest, MessageType type, const M& msg, std::span<const std::byte> tail = {}, double depart = -1) {
    static_assert(std::is_trivially_copyable_v<M>, "messages are plain structs");
    const std::span<const std::byte> parts[2] = {std::as_bytes(std::span<const M, 1>(&msg, 1)), tail};
    send(dest, type, std::span<const std::span<const std::byte>>(parts, 2), depart);
  }
  template <class M>
  bool try_send(NodeId dest, MessageType type, const M& msg, std::span<const std::byte> tail = {},
                double depart = -1) {
    static_assert(std::is_trivially_copyable_v<M>, "messages are plain structs");
    const std::span<const std::byte> parts[2] = {std::as_bytes(std::span<const M, 1>(&msg, 1)), tail};
    return try_send(dest, type, std::span<const std::span<const std::byte>>(parts, 2), depart);
  }

  // --- Receiving ----------------------------------------------------------
  /// Blocks for the next message; the clock becomes max(clock, arrival) and
  /// the gap is booked as `kind`. The returned payload is valid until the
  /// next receive/poll. Throws RunAborted.
  Message receive(WaitKind kind);
  /// The next message if one is queued, without waiting and without moving
  /// the clock (interrupt-level handling: use header.arrival_time).
  bool poll(Message& out);
  /// Cheap check (no clock sample, no system call): may poll() return a
  /// message? False negatives only for mail published after the call.
  /// Under a transport, every 16th call, and every call after one that
  /// found some, first takes one message from the other processes
  /// (Transport::poll): a computing node's checks between pixels then fetch
  /// its requests and rays without waiting for the transport's receiving
  /// thread, which stays off the node's core.
  bool has_mail() {
    if (transport_ && (transport_found_ || (++transport_checks_ & 15u) == 0)) [[unlikely]]
      transport_found_ = transport_->poll();
    return !backlog_.empty() || mailbox_->has_message();
  }
  /// Owner thread only: puts a message that came through the transport
  /// among this node's mail, parked in the arena when the mailbox is full
  /// (the owner cannot wait for room in its own mailbox).
  void accept(const MessageHeader& header, std::span<const std::byte> payload);
  /// Sets a received message aside (a copy in the arena) so that poll()
  /// and receive() skip it until resume_deferred(): for a handler that
  /// waits for one kind of message (svm's page reply) and must leave the
  /// others (work requests, grants) to the main loop, in their order.
  void defer(const Message& m);
  /// Puts the deferred messages back in front of the incoming mail, in the
  /// order they were deferred.
  void resume_deferred();
  /// Moves the clock to `t` if it is behind, booking the gap as `kind`:
  /// what receive() does on a message, for handlers that took the message
  /// with poll() (interrupt level) but had to wait for it.
  void advance_to(double t, WaitKind kind);
  /// Blocks until mail may be there, a run permit was granted, or
  /// `timeout_s` wall seconds passed (0 = no limit), without taking the
  /// mail and without moving the clock. Throws RunAborted.
  void wait_for_mail(double timeout_s);

 private:
  friend class Machine;
  /// Pushes into dest's mailbox (false: full). `costly` is set when the
  /// push did more than copy: a wake-up or a call into the scheduler.
  bool push_to(NodeId dest, MessageHeader& header, std::span<const std::span<const std::byte>> parts,
               bool& costly);
  void sync_compute();
  void end_messaging();
  Message take(const MessageHeader& h, std::span<const std::byte> payload);
  /// Under a transport: counts a ray taken from another process's `source`
  /// and hands its credits back in batches (MachineState::ray_credits).
  void return_ray_credit(NodeId source);
  void check_stop() const;

  MachineState* machine_;
  Transport* transport_ = nullptr;  ///< MachineParams::transport
  std::uint32_t transport_checks_ = 0;  ///< has_mail() calls, for its pulls from the transport
  bool transport_found_ = false;        ///< has_mail()'s last pull took a message
  NodeId id_;
  Arena arena_;
  std::unique_ptr<Mailbox> mailbox_;
  ArenaArray<std::byte> receive_buffer_;
  /// Messages parked while a blocking send waited: header + payload copies.
  struct Parked {
    MessageHeader header;
    std::pmr::vector<std::byte> payload;
    bool counted = false;  ///< already in the received counters (deferred after a poll)
  };
  std::pmr::deque<Parked> backlog_;
  std::size_t park_limit_ = SIZE_MAX;  ///< set_park_limit()
  std::pmr::deque<Parked> deferred_;  ///< set aside by defer(), not seen by poll()
  std::pmr::vector<std::byte> backlog_current_;
  /// Under a transport: rays taken from each sender (by node id, the host
  /// last) whose credits are not handed back yet (return_ray_credit).
  std::pmr::vector<std::int32_t> ray_taken_;
  std::atomic<std::uint8_t> wait_reason_{0};
  std::atomic<std::int64_t> wait_a_{-1}, wait_b_{-1};
  std::atomic<double> clock_seen_{0};  ///< clock_ as of the last wait, for the watchdog
  bool want_permit_ = false;           ///< the last try_run/yield_point was refused
  bool fresh_grant_ = false;           ///< try_run got the permit after a refusal: the next yield_point passes
  double host_nap_s_ = kHostNapMinS;  ///< the host's wait between looks at its mailbox (wait_for_mail)
  bool host_gathering_ = false;       ///< set_host_gathering()
  std::atomic<std::size_t> backlog_size_{0};  ///< messages parked by a blocked send, for the watchdog
  double clock_ = 0;
  double cpu_mark_ = 0;  ///< CPU seconds (kCpu) or metered seconds (kModel) at the last sample
  bool model_clock_ = false;
  double work_price_ = 1;  ///< kModel: applied_corun_slowdown (machine.h), the factor on metered seconds
  double poll_cost_ = 0;   ///< busy seconds per poll(): applied_poll_s (machine.h); 0 for the host
  WorkMeter meter_ = nullptr;
  const void* meter_state_ = nullptr;
  double work_done_s_ = -1;
  BusyTimeline handler_busy_;  ///< the interrupt handler's services (serve_interrupt)
  NodeCounters counters_;
};

}  // namespace raynode::nodes
