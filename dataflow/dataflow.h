// `--mode dataflow`: the paper's data-oriented ray tracer (Badouel,
// Bouatouch & Priol 1994, "Experiments with data-oriented parallelization";
// docs/architecture.md, "dataflow"). The database is partitioned into 3D regions of
// equal estimated load, one per node; rays, not data, travel.
//
// Data flow:
//   host: estimate_load (estimate.h, a subsample of pixels) -> make_partition
//   (region.h, recursive median cuts) -> make_region_databases (region_view.h)
//   -> each node's arena gets its region's primitives, a local grid (uniform,
//   or adaptive: top grid, sub-grids and their tables), the kd-tree of
//   regions and its own primary rays (those entering the scene in its
//   region).
//   node (node_tracer.h): traces a ray inside its region (RegionView + core
//   traversal); a hit there is shaded by core's shading (surface_frame,
//   core::shade_hit, the same code as core::trace_ray) and its shadow,
//   reflected and refracted rays go on; a ray leaving the region is sent to the owner of
//   the next region along it (a RayMsg with pixel id and path weight);
//   ambient, light and background terms go to the host as contributions.
//   Rays received take priority over the node's own primary rays; a ray's
//   local descendants are finished (depth first) before the next message.
//   Sending queue (send_queue.h): a ray whose destination mailbox is full
//   waits in the node's sending queue, which takes the node memory left
//   (DataflowParams::send_queue_slots); the node sends queued rays as
//   their destinations drain and is not passive while any wait.
//   host (host.h): Deadlock avoidance (the paper's "optimistic" strategy): a
//   ray that finds the sending queue full goes to the host, which keeps it
//   (unbounded host memory) and forwards it as soon as the mailbox has room.
//   Termination: Mattern's four-counter method with waves: the host probes
//   every node; a node answers when passive (nothing to trace, buffers
//   flushed) with its counts of work messages sent and received; two
//   consecutive waves with equal totals, sent == received, and an empty host
//   store prove that no ray is anywhere and every contribution is in; then
//   the host shuts the machine down.
//   host: sums contributions per pixel (in arrival order, in double), then
//   divides by spp^2; images equal sequential within float rounding of the
//   sum (about 1e-6 per channel).
//
// Virtual time: a node computes with a run permit (scheduler.h) and yields
// every few rays. Mail is taken with poll() into the node's inbox (an arena
// ring of 4x the mailbox's slots; with the mailbox, the paper's receiving
// queue; a full inbox leaves mail in the mailbox) without moving
// the clock; a received ray is traced once the node's clock has reached its
// arrival — own primary rays fill the gap, and a node with nothing else to
// do advances its clock to the arrival (booked idle). A node marks its work
// done each time it becomes passive; T_p is the latest such time. The
// host's probes and shutdown depart at time 0 (control messages that must
// not move a node's clock); a forwarded spilled ray departs from the host
// at its arrival there plus the network's service cost (optimistic when it
// had to wait for room). Caveat: every messaging call reads the thread's
// CPU clock (a ~0.25 us system call here), part of which lands in the
// node's busy time, so busy time grows with the message count beyond the
// tracing work itself (about 1.7x the one-node work at 4 nodes, 3x at 16 on
// Rings3).
#pragma once

#include <array>
#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

#include "core/database.h"
#include "core/grid.h"
#include "core/image.h"
#include "core/render.h"
#include "dataflow/estimate.h"
#include "dataflow/messages.h"
#include "dataflow/region.h"
#include "nodes/machine.h"

namespace raynode::dataflow {

/// How the scene extent is cut.
enum class PartitionKind {
  kBalanced,  ///< median cuts on the estimated load (the paper's method)
  kEqual,     ///< equal-size regions (the paper's comparison)
};
/// "balanced" / "equal"; throws std::invalid_argument otherwise.
PartitionKind parse_partition(const std::string& name);
const char* partition_name(PartitionKind kind);

/// Node mailbox slots when --queue-capacity is not given: 1024 messages of
/// 256 B, about 330 KiB of a 4 MiB node (plus a 4x larger inbox of ray
/// records, 288 KiB: together the paper's receiving queue).
/// Generous because the emulator runs only a few node threads at a time,
/// so a node's queue fills in wall time while the node waits for the CPU
/// (up to the scheduling window ahead in virtual time), which a real
/// machine's concurrently running node would not see.
inline constexpr std::uint32_t kDefaultQueueCapacity = 1024;

struct DataflowParams {
  core::RenderParams render;      ///< resolution, spp, depth, AOVs (mode and tile size ignored)
  /// nodes, memory, network, topology, mailbox_capacity (--queue-capacity; 0 = kDefaultQueueCapacity)
  nodes::MachineParams machine;
  PartitionKind partition = PartitionKind::kBalanced;
  int subsample = 8;              ///< load estimate: one pixel per subsample x subsample block
  int estimate_resolution = 64;   ///< load estimate: 2D cells along the extent's longer side
  /// Local grids: kind (uniform, the paper's, or adaptive: each region's
  /// own top grid and sub-grids), density, empty-space distances. Uniform by
  /// default here; the CLI passes its --grid (default adaptive).
  core::GridParams grid;
  bool region_aov = false;        ///< also produce the image of the region of each primary hit
  /// Slots of each node's sending queue (send_queue.h), where a ray waits
  /// while its destination's mailbox is full; a ray that finds it full goes
  /// to the host. 0: all the node memory its region and buffers leave (the
  /// paper's message queues, "Deadlock"), at least one mailbox's worth.
  std::size_t send_queue_slots = 0;
};

/// One region, as built and as measured.
struct RegionReport {
  ScreenRect rect;                   ///< ownership rectangle, screen frame (outer sides infinite)
  ScreenRect finite;                 ///< the same clipped to the scene's screen extent
  std::uint32_t node = 0;            ///< owner
  std::size_t primitives = 0;        ///< primitives held (copies of shared ones included)
  std::size_t shared_primitives = 0; ///< of those, also held by another region
  core::GridKind grid_kind = core::GridKind::kUniform;  ///< the local grid's kind (DataflowParams::grid)
  std::size_t grid_references = 0;   ///< the local grid's primitive references (all leaf cells)
  int grid_res[3] = {1, 1, 1};       ///< cells per axis (adaptive: of the top grid)
  std::size_t grid_sub_grids = 0;    ///< adaptive: sub-grids below the top grid (0 for uniform)
  std::size_t grid_leaf_cells = 0;   ///< leaf cells (uniform: all cells)
  std::size_t grid_bytes = 0;        ///< the local grid's arrays (core::Grid::bytes), part of `bytes`
  std::size_t bytes = 0;             ///< region database bytes in the node's arena
  double estimated_cost = 0;         ///< load estimate inside the region
};

/// A node's dataflow counters.
struct NodeFlowStats {
  std::array<nodes::MessageCounts, kRayKindCount> rays_sent{};      ///< to nodes directly, by kind
  std::array<nodes::MessageCounts, kRayKindCount> rays_spilled{};   ///< to the host (sending queue full), by kind
  std::uint64_t rays_queued = 0;        ///< rays that waited in the sending queue for room at their destination
  std::uint64_t send_queue_peak = 0;    ///< most rays in the sending queue at once
  std::array<std::uint64_t, kRayKindCount> rays_received{};         ///< from nodes or the host, by kind
  std::uint64_t primaries = 0;          ///< own primary rays generated
  std::uint64_t segments = 0;           ///< ray segments traced in the region
  std::uint64_t contributions = 0;      ///< colour terms sent
  std::uint64_t contribution_messages = 0;
  std::uint64_t shared_tests = 0;       ///< intersection tests of primitives held by several regions
  std::uint64_t work_sent = 0, work_received = 0;  ///< termination counts
  std::uint64_t waves_answered = 0;
  core::RenderStats tracing;            ///< rays by kind (as sequential counts them), skips, traversal
};

/// The host's counters.
struct HostFlowStats {
  std::uint64_t spilled = 0;            ///< rays received from nodes whose sending queue was full
  std::uint64_t forwarded = 0;          ///< of those, forwarded to their destination
  std::uint64_t forward_retries = 0;    ///< forward attempts that found the destination's mailbox full (one per destination per pass of the host's loop)
  std::uint64_t store_peak = 0;         ///< most rays held at once
  std::uint64_t contributions = 0;      ///< colour terms received
  std::uint64_t first_hits = 0;         ///< AOV records received
  std::uint64_t waves = 0;              ///< termination waves completed
};

struct DataflowResult {
  core::RenderResult render;          ///< image, AOVs, counters summed over the nodes
  core::Image region;                 ///< 1 channel: region of each primary (centre) hit, -1 on a miss (region_aov)
  nodes::RunReport run;               ///< machine counters and virtual times
  std::vector<RegionReport> regions;  ///< per region (= per node)
  std::vector<NodeFlowStats> per_node;
  HostFlowStats host;
  LoadEstimate estimate;              ///< the subsample's cost grid and its host time
  ScreenRect extent;                  ///< the scene's screen extent (the estimate's cost grid may cover less)
  PartitionKind partition = PartitionKind::kBalanced;
  double setup_s = 0;                 ///< host wall seconds to partition and build the region databases

  /// Ray messages between nodes plus spills, all kinds.
  std::uint64_t ray_messages() const;
  /// Spilled rays / all ray messages sent by nodes (the paper: ~0.5%).
  double spill_fraction() const;
  /// Per node: busy time / T_p; and their mean (the paper's "average load").
  std::vector<double> measured_load() const;
  double average_load() const;
  /// The "dataflow" object of --stats: partition, estimate, ray messages by
  /// kind and bytes, spills, shared-primitive tests, estimated vs measured
  /// load per node, average load; times in seconds, bytes in bytes.
  nlohmann::json to_json() const;
};

/// Renders `db` in dataflow mode. Throws std::runtime_error "dataflow mode:
/// region R needs X ..., --node-memory is Y" before any node starts when a
/// region does not fit its node; NodeError for failures inside the run;
/// std::invalid_argument for bad parameters. `grid` is the host's grid,
/// uniform or adaptive (used by the load estimate and for the scene box;
/// the nodes trace their own local grids, params.grid).
DataflowResult render_dataflow(const core::Database& db, const core::Grid& grid, const DataflowParams& params);

}  // namespace raynode::dataflow
