// The --stats document of `raynode render` (its keys: README.md, "Reading
// the statistics"; tests/cli/golden/ pins them per mode): the scene, the
// image, the rays and tests, the times, the grid, and the node modes'
// machine report, per-node counters and svm's or dataflow's objects.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "apps/node_runs.h"
#include "core/cell_blocks.h"
#include "core/database.h"
#include "core/grid.h"
#include "core/image.h"
#include "core/render.h"
#include "core/scene.h"
#include "modes/modes.h"

namespace raynode::apps {

/// What a frame produced besides the RenderResult (node modes only).
struct FrameExtras {
  nlohmann::json nodes;  ///< the machine report ("nodes" in --stats), null for in-process modes
  core::Image node;      ///< --aov node
  core::Image pages;     ///< --aov pages (svm)
  nlohmann::json svm;    ///< the "svm" object of --stats
  core::Image region;    ///< --aov region (dataflow)
  nlohmann::json dataflow;  ///< the "dataflow" object of --stats
  ModelCalibration calibration;  ///< the model clock checked on the scene (--calibrate)
};

/// Fills `extras`' JSON objects from a node-mode run `r` of `nodes` nodes:
/// the machine report with its work counters and efficiency estimate, and
/// svm's or dataflow's object. Leaves them null for an in-process mode.
void node_mode_json(const modes::RunResult& r, int nodes, FrameExtras& extras);

/// What one render reports: its request, its result and their context.
struct RenderRecord {
  std::string scene_spec;            ///< the SCENE argument
  int tessellate = 0;                ///< -t
  double floor = 0;                  ///< --floor (0: none)
  std::string mode, accel, output;   ///< --mode, --accel, -o
  int nodes = 1;                     ///< --nodes
  const core::RenderParams& params;
  const core::RenderResult& result;
  double wall_s = 0, cpu_s = 0;      ///< the frame's seconds
  const core::Scene& scene;
  const core::Database& db;
  const core::Grid* grid = nullptr;          ///< --accel grid
  const core::CellBlocks* blocks = nullptr;  ///< the grid's packed cells, if any
  double build_s = 0;                ///< the accelerator's build, wall seconds
  bool skip_empty = true;            ///< --skip-empty
  const FrameExtras& extras;
  const std::vector<std::pair<std::string, std::string>>& aov_files;  ///< (AOV, path) written
};

/// The --stats document of `r`.
nlohmann::json render_stats_json(const RenderRecord& r);

}  // namespace raynode::apps
