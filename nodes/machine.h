// The emulated distributed-memory machine: N node threads plus a host, each
// with its own arena and mailbox, a topology and a network cost model
// (docs/architecture.md, "The node emulator").
//
// Place in the data flow: a mode (replicated, svm, dataflow) builds
// MachineParams, then Machine::run(node_main, host_main, setup):
//   1. creates every participant's NodeContext (arena, mailbox);
//   2. calls setup(ctx) for each node on the caller's thread (the host
//      loading node memories before the nodes start; not in virtual time);
//   3. runs node_main(ctx) on one thread per node and host_main(host ctx) on
//      one more thread, and waits for all of them;
//   4. calls teardown(ctx) for each node (always), then returns a RunReport: each node's counters and final clock; parallel
//      time T_p = the largest node clock.
// An exception in any participant stops the run (the others' blocking calls
// throw RunAborted) and is rethrown by run() as NodeError naming the node.
// With timeout_s > 0 a watchdog stops a run that takes longer (wall clock),
// and with stall_timeout_s > 0 one that sends no message for that long (no
// progress: every mode sends pixels or contributions as it works); either
// throws NodeError for the host naming what each node was waiting for
// (NodeContext::describe_wait): no hang survives it.
//
// Speedup and efficiency (the paper's definitions): speedup = T_1 / T_p
// with T_1 the one-node run's parallel time, efficiency = speedup / p.
#pragma once

#include <atomic>
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <optional>
#include <mutex>
#include <nlohmann/json_fwd.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/cost_model.h"
#include "nodes/links.h"
#include "nodes/node.h"
#include "nodes/scheduler.h"
#include "nodes/transport.h"

namespace raynode::nodes {

inline constexpr std::size_t kMiB = std::size_t(1) << 20;

/// How the machine is built. Every field has a default.
struct MachineParams {
  std::uint32_t nodes = 1;                    ///< 1 .. kMaxNodes
  std::size_t node_memory = 4 * kMiB;         ///< bytes per node arena (iPSC/2: 4 MiB)
  TopologyKind topology = TopologyKind::kHypercube;
  NetworkModel network;                       ///< default: "none"
  std::uint32_t mailbox_capacity = 0;         ///< slots per node mailbox; 0 = 2 x nodes + 32
  std::uint32_t host_mailbox_capacity = 4096; ///< slots of the host's mailbox
  std::uint32_t max_payload = 256;            ///< bytes per message payload, at most
  double timeout_s = 0;                       ///< watchdog, wall seconds; 0 = none
  /// Watchdog: stop the run when no message was sent for this many wall
  /// seconds, reporting what each node waits for; 0 = off.
  double stall_timeout_s = 0;
  /// Virtual-time scheduling (scheduler.h): at most `run_permits` nodes
  /// compute at once (0 = the host's hardware threads), the laggards first;
  /// a node more than `schedule_window_s` virtual seconds ahead of a
  /// waiting one hands over. A negative window turns scheduling off.
  std::uint32_t run_permits = 0;
  double schedule_window_s = 200e-6;
  /// With scheduling on: is a node without a permit woken for its mail by a
  /// service permit (scheduler.h, "Mail service") rather than by each
  /// message? Same virtual times, fewer thread switches; it pays where mail
  /// is not waited for (dataflow's rays: 10-40% less wall time at 4-64
  /// nodes), not where a node blocks for each reply (work grants, pages).
  /// Unset: the mode's default (dataflow on, replicated and svm off).
  std::optional<bool> scheduled_mail;
  /// Where idle nodes send work requests (work.h; `--work-requests`).
  WorkRequestRoute work_request_route = WorkRequestRoute::kRing;
  /// What a busy node grants a work request (work.h; `--work-grants`);
  /// kAuto is resolved by the Machine (resolved_work_grant).
  WorkGrant work_grant = WorkGrant::kAuto;
  /// What advances a node's clock while it computes (node.h, "Virtual time").
  ComputeClock clock = ComputeClock::kCpu;
  /// Model clock, runs of more than one node: a node's metered work costs
  /// this many times its one-node price (>= 1). It describes nodes that
  /// share a host's cores, caches and memory bandwidth (MPI ranks on one
  /// machine: `raynode bench mpi` measures it as a probe node's busy time
  /// beside the other ranks' nodes over its time alone); 1 for nodes that
  /// share nothing, as the iPSC/2's. The CPU clock ignores it: it measures
  /// the emulator's own threads as they share this host.
  double corun_slowdown = 1;
  /// The unit costs the modes' work meters use under ComputeClock::kModel.
  core::CostModel cost_model = core::default_cost_model();
  /// Null: every participant runs in this process (the emulator). Else this
  /// process runs only those `transport` places here, one node per process
  /// (nodes must equal transport->processes()), and the rest are reached
  /// through it (transport.h). The virtual-time scheduler and link
  /// contention are then off: each process has its own cores and the links
  /// are real. Not owned; must outlive the Machine's runs.
  Transport* transport = nullptr;
};

inline constexpr std::uint32_t kMaxNodes = 4096;
/// The largest MachineParams::corun_slowdown accepted.
inline constexpr double kMaxCorunSlowdown = 100;

/// An exception thrown in a node (or the host), carried out of the run.
class NodeError : public std::runtime_error {
 public:
  NodeError(NodeId node, const std::string& message, bool does_not_fit = false)
      : std::runtime_error(message), node(node), does_not_fit(does_not_fit) {}
  NodeId node;
  bool does_not_fit;  ///< the cause was a DoesNotFit (a node ran out of its memory)
};

/// One participant's results.
struct NodeReport {
  NodeId id = 0;
  NodeCounters counters;
  double clock_s = 0;            ///< final virtual time
  double work_done_s = -1;       ///< virtual time its work ended (mark_work_done), -1 if never marked
  std::size_t memory_peak = 0;   ///< arena high-water mark, bytes
  std::size_t memory_budget = 0; ///< arena budget, bytes
  double wall_s = 0;             ///< real seconds its main function ran (under MPI: the rank's wall clock)
};

/// What a run measured.
struct RunReport {
  std::vector<NodeReport> nodes;
  NodeReport host;
  double parallel_time_s = 0;  ///< T_p: the latest end of work (or final clock) over the nodes, virtual seconds
  double wall_s = 0;           ///< real seconds the run took
  std::string network;         ///< preset name
  std::string transport;       ///< empty: the emulator; else the transport's name ("mpi")
  bool contention = false;     ///< links contend (NetworkModel::contention)
  std::string topology;
  std::string clock;           ///< "cpu" or "model" (MachineParams::clock)
  double corun_slowdown = 1;   ///< the factor the model clock applied to the nodes' work (applied_corun_slowdown)
  std::string work_requests;   ///< "ring", "last-grantor" or "off" (MachineParams::work_request_route)
  std::string work_grants;     ///< "item", "nearest" or "half" (MachineParams::work_grant)
  /// The virtual-time scheduler's work (scheduler.h): compute permits
  /// granted, of them taken back a window ahead, and service permits
  /// granted for mail; all 0 with scheduling off.
  std::uint64_t compute_grants = 0, handoffs = 0, service_grants = 0;
  bool scheduled_mail = false;

  /// Counters summed over the nodes (not the host).
  NodeCounters total() const;
  /// {"count", "parallel_time_s", "wall_s", "network", "topology", "total": {...},
  ///  "per_node": [...] (when per_node)}; times in seconds, bytes in bytes.
  nlohmann::json to_json(bool per_node = true) const;
};

/// Shared state of a run: what every participant may touch. Internal to
/// nodes/, public for NodeContext.
class MachineState {
 public:
  explicit MachineState(const MachineParams& params);
  ~MachineState();

  const MachineParams params;
  const Topology topology;
  std::vector<std::unique_ptr<NodeContext>> nodes;
  std::unique_ptr<NodeContext> host;  ///< null where a transport runs the host in another process
  std::atomic<bool> stop{false};
  std::atomic<bool> host_finished{false};  ///< the host's main returned
  std::unique_ptr<std::atomic<bool>[]> finished;  ///< per node: its main returned
  std::unique_ptr<Scheduler> scheduler;
  std::unique_ptr<LinkNetwork> links;  ///< the links in virtual time, under NetworkModel::contention
  std::atomic<std::uint64_t> progress{0};  ///< messages sent so far (the stall watchdog's measure)
  /// Under a transport, ray messages (kRay) to another process's node
  /// travel on credits, so that a send there is refused as a send to a full
  /// mailbox is in the emulator (dataflow then queues or spills the ray,
  /// the paper's rule): each sender may have `ray_window` rays taken by no
  /// one yet per destination node, and the destination hands credits back
  /// as it takes them (NodeContext::take). Empty without a transport.
  std::unique_ptr<std::atomic<std::int32_t>[]> ray_credits;
  std::int32_t ray_window = 0;  ///< max(1, mailbox slots / nodes): the senders share a mailbox
  /// Credit messages each participant (the nodes, then the host) has
  /// received. The receiving process's delivery books a credit, which no
  /// participant takes from its mailbox, so the run's report adds these to
  /// the participant's received kControl counts. Empty without a transport.
  std::unique_ptr<std::atomic<std::uint64_t>[]> credits_received;
  /// The credits `from` (a node or the host) holds for sending rays to node `to`.
  std::atomic<std::int32_t>& ray_credit(NodeId from, NodeId to) {
    return ray_credits[std::size_t(from == kHost ? params.nodes : from) * params.nodes + to];
  }

  NodeContext& context(NodeId id) { return id == kHost ? *host : *nodes[id]; }
  /// Does this process run participant `id` (always, without a transport)?
  bool is_local(NodeId id) const { return id == kHost ? host != nullptr : nodes[id] != nullptr; }
  /// Records the first failure and stops everyone.
  void fail(NodeId node, std::exception_ptr error);
  /// Sets `stop` and wakes every mailbox.
  void stop_all();
  std::exception_ptr error() const;
  NodeId error_node() const;

 private:
  mutable std::mutex error_mutex_;
  std::exception_ptr error_;
  NodeId error_node_ = 0;
};

class Machine {
 public:
  using Main = std::function<void(NodeContext&)>;

  /// Validates params: throws std::invalid_argument for 0 or too many nodes,
  /// a zero memory budget or payload limit, or nodes x node memory beyond
  /// the host's physical memory (check_nodes_fit_host; with a transport, one
  /// node's memory), or a node count other than the transport's processes.
  /// Allocates nothing.
  explicit Machine(const MachineParams& params);

  const MachineParams& params() const { return params_; }

  /// Runs one frame as described in the file comment. `teardown(ctx)`, if
  /// given, runs for every node on the caller's thread after all threads
  /// ended (also when the run failed), before the arenas go: the place to
  /// free what setup put in them. Throws NodeError.
  /// With a transport, the setup, mains and teardown run only for this
  /// process's participants; the report's per-node entries are gathered to
  /// process 0 (the host's), whose report is complete. A failure stops this
  /// process's run and is thrown here; the caller must end the job (the
  /// other processes cannot be told).
  RunReport run(const Main& node_main, const Main& host_main, const Main& setup = {}, const Main& teardown = {});

  /// With a transport, collects each node's entry of `per_node` (one per
  /// node, filled by that node's process, e.g. in teardown) into process
  /// 0's vector; collective. Without one, there is nothing to collect.
  template <class T>
  void gather(std::vector<T>& per_node) const {
    if (params_.transport) gather_per_node(*params_.transport, per_node);
  }

 private:
  MachineParams params_;
};

/// "cpu" or "model" (--clock). Throws std::invalid_argument naming the text.
ComputeClock parse_compute_clock(const std::string& text);
/// "cpu" or "model".
const char* compute_clock_name(ComputeClock c);
/// "ring", "last-grantor" or "off" (--work-requests). Throws std::invalid_argument naming the text.
WorkRequestRoute parse_work_request_route(const std::string& text);
/// "ring", "last-grantor" or "off".
const char* work_request_route_name(WorkRequestRoute r);
/// "auto", "item", "nearest" or "half" (--work-grants). Throws std::invalid_argument naming the text.
WorkGrant parse_work_grant(const std::string& text);
/// "auto", "item", "nearest" or "half".
const char* work_grant_name(WorkGrant g);
/// The rule a machine with `params` runs: params.work_grant, with kAuto
/// resolved to kHalf on a transport and kItem in the emulator (the paper's).
WorkGrant resolved_work_grant(const MachineParams& params);

/// Whether the described costs of nodes sharing a machine apply: an emulated
/// machine of more than one node (a lone node has none beside it; on a
/// transport's processes the nodes really share their hosts, and their
/// clocks see it).
inline bool charges_sharing(const MachineParams& params) { return params.nodes > 1 && !params.transport; }

/// The factor a node's metered work is priced at: corun_slowdown under the
/// model clock where charges_sharing, else 1.
inline double applied_corun_slowdown(const MachineParams& params) {
  return params.clock == ComputeClock::kModel && charges_sharing(params) ? params.corun_slowdown : 1.0;
}

/// The busy seconds a node is charged per look for mail: network.poll_s
/// where charges_sharing (either clock), else 0.
inline double applied_poll_s(const MachineParams& params) {
  return charges_sharing(params) ? params.network.poll_s : 0.0;
}

/// The largest byte size parse_bytes accepts: 2^62 B (4 EiB), far above any
/// host, so that sizes and their sums stay clear of size_t overflow.
inline constexpr std::size_t kMaxByteSize = std::size_t(1) << 62;

/// Parses a byte size: "4MiB", "512KiB", "1GiB", "4M", "1048576" (bytes).
/// Throws std::invalid_argument with the text on a malformed or zero size,
/// and naming kMaxByteSize on one above it (never wraps).
std::size_t parse_bytes(const std::string& text);

/// The host's physical memory in bytes (sysconf _SC_PHYS_PAGES x page
/// size), or 0 when unknown.
std::size_t host_physical_memory();

/// Throws std::invalid_argument, naming the node count, the node memory,
/// their product and the host's memory, when nodes x node_memory (bytes)
/// exceeds host_bytes (0 = unknown: no check). Arenas charge what the nodes
/// allocate as they go and reserve nothing up front, so their budgets are
/// limits rather than allocations: budgets summing beyond the host's memory
/// would let the nodes together exhaust the host before any arena refuses.
void check_nodes_fit_host(std::uint32_t nodes, std::size_t node_memory, std::size_t host_bytes);

}  // namespace raynode::nodes
