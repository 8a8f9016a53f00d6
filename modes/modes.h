// Every rendering mode behind one call: a typed request in, a typed result
// out. The in-process modes (sequential, shared) run core::render_image;
// the node modes run on the emulated machine: replicated (nodes/
// replicated.h, the database copied to every node), svm (svm/svm.h, the
// paper's shared virtual memory) and dataflow (dataflow/dataflow.h, the
// paper's ray dataflow). The CLI (apps/) decodes its options into a
// RunRequest once, and render, bench and sweep all call render().
//
// Place in the data flow: apps (options -> RunRequest) -> modes::render ->
// a mode's render_* -> RunResult -> apps (images, --stats JSON, tables).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "core/cell_blocks.h"
#include "core/database.h"
#include "core/embree_scene.h"
#include "core/grid.h"
#include "core/image.h"
#include "core/render.h"
#include "dataflow/dataflow.h"
#include "nodes/machine.h"
#include "control/replicated.h"
#include "control/submap_plan.h"
#include "svm/svm.h"

namespace raynode::modes {

enum class Mode { kSequential, kShared, kReplicated, kSvm, kDataflow };

/// "sequential", "shared", "replicated", "svm" or "dataflow"; throws
/// std::invalid_argument naming the others for any other name.
Mode parse_mode(std::string_view name);
const char* mode_name(Mode mode);
/// True for the modes that run on the emulated machine.
inline bool is_node_mode(Mode mode) { return mode != Mode::kSequential && mode != Mode::kShared; }

/// What the node modes read besides the render's parameters; each field
/// names the modes that read it.
struct NodeModeParams {
  nodes::MachineParams machine;       ///< all node modes: nodes, memory, network, clock, ...
  std::int32_t item_w = 3, item_h = 3;  ///< replicated, svm: work item, pixels
  control::SubmapParams submaps;        ///< replicated, svm: the initial distribution
  std::uint32_t page_size = 1024;     ///< svm: bytes
  std::optional<svm::DirectoryOrder> directory_order;  ///< svm; nullopt = bricked on several nodes
  std::optional<svm::PrimitiveOrder> primitive_order;  ///< svm; nullopt = auto (svm::SvmParams::primitive_order)
  std::uint32_t cache_pages = 0;      ///< svm: frames per node; 0 = all free memory
  double cache_fraction = 0;          ///< svm: of the database's pages, used when > 0
  std::uint32_t pack_min = 0;         ///< svm: page packed cells of at least this many triangles; 0 = the paper's object lists
  bool fetch_by_get = false;          ///< svm: one-sided page reads through the machine's transport (--page-fetch get)
  int subsample = 8;                  ///< dataflow: load estimate, one pixel per NxN block
  dataflow::PartitionKind partition = dataflow::PartitionKind::kBalanced;  ///< dataflow
  std::uint32_t queue_capacity = 0;   ///< dataflow: mailbox slots; 0 = the mode's default
  std::uint32_t send_queue = 0;       ///< dataflow: sending queue slots; 0 = the node memory left
};

/// One frame's request.
struct RunRequest {
  Mode mode = Mode::kSequential;
  core::RenderParams render;          ///< size, samples, depth, AOVs, progress counter; `mode` is set by render()
  NodeModeParams nodes;               ///< node modes only
  bool node_aov = false;              ///< node modes: which node rendered each pixel (dataflow: each pixel's region)
  bool pages_aov = false;             ///< svm: distinct pages per pixel
  bool region_aov = false;            ///< dataflow: the region of each pixel's first hit
  const core::EmbreeScene* embree = nullptr;  ///< in-process modes: trace with Embree instead of the grid
  const core::CellBlocks* blocks = nullptr;   ///< in-process modes: the grid's packed cells
};

/// One frame's results. The node modes' own results are kept whole, except
/// their images, which are moved to `render` and the AOVs here.
struct RunResult {
  core::RenderResult render;  ///< colour, core's AOVs, counters summed over threads or nodes
  core::Image node;           ///< node_aov: the node of each pixel (1 channel)
  core::Image pages;          ///< pages_aov: distinct pages per pixel (1 channel)
  core::Image region;         ///< region_aov: region of each pixel's first hit, -1 on a miss
  std::optional<control::ReplicatedResult> replicated;
  std::optional<svm::SvmResult> svm;
  std::optional<dataflow::DataflowResult> dataflow;

  /// The emulated machine's report; null for the in-process modes.
  const nodes::RunReport* run() const;
  /// Each node's work counters (replicated, svm); null otherwise.
  const std::vector<control::WorkStats>* work() const;
  /// Each node's tracing counters (replicated, svm); null otherwise.
  const std::vector<core::RenderStats>* tracing() const;
};

/// Renders `db` as `req` says, with its host `grid` (null only when
/// req.embree is set: the node modes need the grid). Throws
/// std::invalid_argument for a request that makes no sense (an AOV its mode
/// has not, Embree or several nodes with an in-process mode, Embree with a
/// node mode) or bad parameters; nodes::DoesNotFit when a node mode's
/// database does not fit its nodes; nodes::NodeError for failures inside a
/// run; core::RenderTimeout and core::StopError as core::render_image.
RunResult render(const core::Database& db, const core::Grid* grid, const RunRequest& req);

}  // namespace raynode::modes
