// The static submaps of the control-oriented modes (svm, replicated;
// `--submaps`): the paper's near-square parts of equal area
// (SubmapRule::kSquare, section "Scheduling"), or parts of near-equal
// estimated cost (kBalanced), so that fewer pixels move by work requests.
//
// Why balanced: the paper balances the load dynamically, idle nodes taking
// 3x3-pixel work items from busy ones. In svm every such item is rendered
// far from the node's own submap, so its pages are cold: on tetra:9 at 64
// nodes (512x512) a node renders up to 40% of its pixels in items it was
// granted, and most of the run's page faults are theirs. Cutting the image
// by cost, as the paper's data-oriented algorithm cuts the scene
// ("Static load balancing": subsample the image, count the work), leaves
// the work items to mop up what the estimate missed.
//
// The estimate: the host traces one pixel per subsample x subsample block
// (its centre, or the nearest pixel inside the image) with the sequential
// tracer over its own Database and Grid, and every pixel of the block
// costs the traced pixel's modelled seconds (core::CostModel over its rays
// and traversal counts, the model clock's cost). Host work before the
// run, outside virtual time, like building the grid and the pages; its
// cost is reported (SubmapPlan::estimate_*).
//
// Place in the data flow: mode's setup (host Database + Grid + camera) ->
// plan_submaps -> SubmapPlan::rects (per node) -> run_work_farm.
#pragma once

#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <vector>

#include "core/camera.h"
#include "core/cost_model.h"
#include "core/database.h"
#include "core/grid.h"
#include "core/render.h"
#include "control/work.h"

namespace raynode::control {

/// How to cut the image (`--submaps`, `--subsample`).
struct SubmapParams {
  SubmapRule rule = SubmapRule::kSquare;
  int subsample = 8;  ///< kBalanced: one traced pixel per subsample x subsample block (>= 1)
};

/// The host's estimate of each pixel's cost (SubmapRule::kBalanced).
struct PixelCostEstimate {
  std::vector<double> cost;  ///< width x height, row-major: modelled seconds of the block's traced pixel
  std::uint64_t pixels = 0;  ///< pixels traced
  std::uint64_t rays = 0;    ///< rays traced (all kinds)
  double model_s = 0;        ///< modelled seconds of the traced pixels (their cost on one node)
  double wall_s = 0;         ///< host wall seconds of the estimate
};

/// Traces one pixel per subsample x subsample block of camera's image
/// (camera.width() x camera.height()) with the sequential tracer over `db`
/// and `grid` at `render`'s spp, depth and pruning, and charges each block
/// the traced pixel's modelled seconds under `model`. Throws
/// std::invalid_argument for subsample < 1.
PixelCostEstimate estimate_pixel_cost(const core::Database& db, const core::Grid& grid, const core::Camera& camera,
                                      const core::RenderParams& render, int subsample, const core::CostModel& model);

/// The nodes' submaps and how they were made.
struct SubmapPlan {
  std::vector<Rect> rects;  ///< per node (index = node id)
  SubmapParams params;
  /// kBalanced: the estimate (its cost array is dropped once the cuts are made).
  PixelCostEstimate estimate;
  /// kBalanced: the largest submap's estimated cost over the mean (1 = the
  /// estimate's parts are equal); 0 under kSquare.
  double estimated_max_over_mean = 0;

  /// {"rule", "subsample", and under kBalanced "estimate": {"pixels",
  /// "rays", "model_s", "wall_s", "max_over_mean"}}.
  nlohmann::json to_json() const;
};

/// The submaps of `nodes` nodes over camera's image under `params`:
/// make_submaps (kSquare), or make_balanced_submaps over
/// estimate_pixel_cost (kBalanced; at one node the whole image, with no
/// estimate traced: plan.estimate stays empty, max over mean 1). Throws
/// std::invalid_argument for bad params.
SubmapPlan plan_submaps(const core::Database& db, const core::Grid& grid, const core::Camera& camera,
                        const core::RenderParams& render, std::uint32_t nodes, const SubmapParams& params,
                        const core::CostModel& model);

}  // namespace raynode::control
