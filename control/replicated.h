// `--mode replicated`: every node holds a full copy of the database in its
// own arena and runs the sequential tracer on the pixels it is given — the
// "without dataflow" row of the paper's Table 1, the reference the svm and
// dataflow modes are measured against. Pixels are distributed as in svm
// (work.h: square or balanced submaps plus work items stolen along the
// ring); the host
// gathers them into the frame.
//
// Place in the data flow: host Database + Grid -> setup copies the arrays
// (DatabaseArrays) into each node's arena -> node: DirectView over its copy
// -> core::render_pixel per pixel -> kPixels messages -> host frame buffer.
// The arithmetic is the sequential tracer's on the same values, so the image
// is bit-identical to `--mode sequential` for every node count.
#pragma once

#include <cstdint>
#include <vector>

#include "core/database.h"
#include "core/grid.h"
#include "core/render.h"
#include "nodes/machine.h"
#include "control/submap_plan.h"
#include "control/work.h"

namespace raynode::control {

struct ReplicatedParams {
  core::RenderParams render;  ///< resolution, spp, depth, AOVs (mode and tile size ignored)
  MachineParams machine;      ///< nodes, memory, network, topology (payload sized automatically)
  std::int32_t item_w = 3;    ///< work item, pixels (--work-item WxH)
  std::int32_t item_h = 3;
  SubmapParams submaps;       ///< the static submaps (--submaps, --subsample; submap_plan.h)
  bool node_aov = false;      ///< also produce the image of which node computed each pixel
};

struct ReplicatedResult {
  core::RenderResult render;               ///< image, AOVs, counters summed over the nodes
  core::Image node;                        ///< 1 channel: id of the node that computed the pixel (node_aov)
  RunReport run;                           ///< machine counters and virtual times
  std::vector<WorkStats> work;             ///< per node
  std::vector<core::RenderStats> tracing;  ///< per node
  std::size_t database_bytes = 0;          ///< bytes of each node's copy
  SubmapPlan submaps;                      ///< the nodes' submaps and, if balanced, the estimate's cost
};

/// Bytes each node needs to hold the database copy: the arrays plus lights.
std::size_t replicated_bytes_per_node(const core::Database& db, const core::Grid& grid);

/// Renders `db` in replicated mode. Throws std::runtime_error "replicated
/// mode: the database needs X per node, --node-memory is Y" before starting
/// when a copy does not fit beside the node's mailbox; NodeError for
/// failures inside the run; std::invalid_argument for bad parameters.
ReplicatedResult render_replicated(const core::Database& db, const core::Grid& grid, const ReplicatedParams& params);

}  // namespace raynode::control
