#include "control/submap_plan.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "core/direct_view.h"
#include "core/shade.h"

namespace raynode::control {

namespace {

/// std::invalid_argument unless subsample >= 1 (the estimate's block side).
void check_subsample(int subsample) {
  if (subsample < 1) throw std::invalid_argument(fmt::format("subsample must be >= 1, got {}", subsample));
}

}  // namespace

PixelCostEstimate estimate_pixel_cost(const core::Database& db, const core::Grid& grid, const core::Camera& camera,
                                      const core::RenderParams& render, int subsample, const core::CostModel& model) {
  check_subsample(subsample);
  const auto t0 = std::chrono::steady_clock::now();
  const int w = camera.width(), h = camera.height();
  const core::DirectView view(db, grid);
  const core::ShadingContext shading =
      core::make_shading_context(db.lights, db.background, render.max_depth, render.min_weight, render.shadow_rays);
  auto scratch = std::make_unique<core::ShadingScratch>();  // its mailbox is 4 KiB
  PixelCostEstimate out;
  out.cost.assign(std::size_t(w) * std::size_t(h), 0.0);
  for (int by = 0; by < h; by += subsample)
    for (int bx = 0; bx < w; bx += subsample) {
      const int x1 = std::min(bx + subsample, w), y1 = std::min(by + subsample, h);
      // Counters from zero: the pixel's own counts.
      scratch->stats.rays = {};
      scratch->traversal.stats = {};
      core::render_pixel(view, shading, camera, (bx + x1) / 2, (by + y1) / 2, render.spp, false, *scratch);
      const double cost = model.seconds(scratch->stats.rays, scratch->traversal.stats);
      out.rays += scratch->stats.rays.total();
      for (int y = by; y < y1; ++y)
        std::fill(out.cost.begin() + std::ptrdiff_t(y) * w + bx, out.cost.begin() + std::ptrdiff_t(y) * w + x1, cost);
      ++out.pixels;
      out.model_s += cost;
    }
  out.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

SubmapPlan plan_submaps(const core::Database& db, const core::Grid& grid, const core::Camera& camera,
                        const core::RenderParams& render, std::uint32_t nodes, const SubmapParams& params,
                        const core::CostModel& model) {
  SubmapPlan plan;
  plan.params = params;
  const int w = camera.width(), h = camera.height();
  if (params.rule == SubmapRule::kSquare) {
    plan.rects = make_submaps(w, h, nodes);
    return plan;
  }
  // One node's one submap is the whole image, whatever the costs: no
  // estimate to trace (nor to charge against T_1).
  if (nodes == 1) {
    check_subsample(params.subsample);
    plan.rects = make_submaps(w, h, 1);
    plan.estimated_max_over_mean = 1.0;
    return plan;
  }
  plan.estimate = estimate_pixel_cost(db, grid, camera, render, params.subsample, model);
  std::vector<double> parts;  // each submap's estimated cost, for the report
  plan.rects = make_balanced_submaps(w, h, nodes, plan.estimate.cost, &parts);
  double total = 0, most = 0;
  for (const double part : parts) {
    total += part;
    most = std::max(most, part);
  }
  plan.estimated_max_over_mean = total > 0 ? most / (total / double(nodes)) : 1.0;
  plan.estimate.cost = {};
  return plan;
}

nlohmann::json SubmapPlan::to_json() const {
  nlohmann::json j;
  j["rule"] = submap_rule_name(params.rule);
  if (params.rule == SubmapRule::kBalanced) {
    j["subsample"] = params.subsample;
    j["estimate"] = {{"pixels", estimate.pixels},
                     {"rays", estimate.rays},
                     {"model_s", estimate.model_s},
                     {"wall_s", estimate.wall_s},
                     {"max_over_mean", estimated_max_over_mean}};
  }
  return j;
}

}  // namespace raynode::control
