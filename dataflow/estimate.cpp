#include "dataflow/estimate.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <stdexcept>

#include "core/render.h"

namespace raynode::dataflow {

namespace {

/// nx x ny cells of (near) square shape over the extent, `resolution` along the longer side.
void grid_shape(const ScreenRect& e, int resolution, int& nx, int& ny) {
  const double w = double(e.x1) - e.x0, h = double(e.y1) - e.y0;
  if (w >= h) {
    nx = resolution;
    ny = std::max(1, int(std::lround(resolution * (w > 0 ? h / w : 1.0))));
  } else {
    ny = resolution;
    nx = std::max(1, int(std::lround(resolution * (h > 0 ? w / h : 1.0))));
  }
}

}  // namespace

std::vector<std::uint32_t> cost_bins_of_cells(const core::Grid& grid, const CameraFrame& frame, const CostGrid& cost) {
  const ScreenRect& e = cost.extent;
  const double sx = cost.nx / (double(e.x1) - e.x0), sy = cost.ny / (double(e.y1) - e.y0);
  std::vector<std::uint32_t> bin(grid.leaf_cells());
  // The cells of one grid (a uniform grid, or one of an adaptive grid's
  // SubGrids): cell c is leaf first + c (core/grid.h, SubGrid).
  auto bin_of = [&](const core::Vec3& centre) {
    const int bx = std::clamp(int(std::floor((frame.x(centre) - e.x0) * sx)), 0, cost.nx - 1);
    const int by = std::clamp(int(std::floor((frame.y(centre) - e.y0) * sy)), 0, cost.ny - 1);
    return std::uint32_t(by * cost.nx + bx);
  };
  auto bin_cells = [&](const core::GridInfo& g, std::uint32_t first) {
    for (int z = 0; z < g.res[2]; ++z)
      for (int y = 0; y < g.res[1]; ++y)
        for (int x = 0; x < g.res[0]; ++x) bin[first + g.cell_index(x, y, z)] = bin_of(g.cell_bounds(x, y, z).center());
  };
  if (grid.sub_grids.empty()) {
    bin_cells(grid.info, 0);
  } else {
    for (const core::SubGrid& g : grid.sub_grids) {
      bin_cells(g.info, g.first_entry);
      // The large primitives beside a sub-grid: charged where the sub-grid is.
      if (g.large_list) bin[g.first_entry + g.info.cell_count()] = bin_of(g.info.bounds.center());
    }
  }
  return bin;
}

CostGrid uniform_cost(const ScreenRect& extent, int resolution) {
  if (resolution < 1) throw std::invalid_argument("cost grid resolution must be >= 1");
  CostGrid c;
  c.extent = extent;
  grid_shape(extent, resolution, c.nx, c.ny);
  c.cost.assign(std::size_t(c.nx) * c.ny, 1.0);
  return c;
}

namespace {

/// Adds `work`, the tests of the scene's large primitives beside the top
/// grid (CostView), to the cost cells in proportion to their other work:
/// every ray tests them, where its walk charges the rest (evenly, when
/// nothing else was charged).
void charge_beside_top(double work, CostGrid& c) {
  const double others = c.total();
  for (double& v : c.cost) v += others > 0 ? work * (v / others) : work / double(c.cost.size());
}

/// One pass of estimate_load over the cost grid `c` (its extent and shape
/// set, costs zeroed).
void charge(const core::Database& db, const core::Grid& grid, const core::Camera& camera, const CameraFrame& frame,
            const EstimateParams& params, CostGrid& c, LoadEstimate& out) {
  const std::vector<std::uint32_t> bin = cost_bins_of_cells(grid, frame, c);
  const core::DirectView base(db, grid);
  double beside_top = 0;
  const CostView view(base, bin.data(), c.cost.data(), &beside_top);
  const core::ShadingContext ctx = core::make_shading_context(db, params.max_depth, params.min_weight, params.shadow_rays);
  core::ShadingScratch scratch;
  const int s = params.subsample, half = s / 2;
  out.pixels = 0;
  for (int y = half < camera.height() ? half : 0; y < camera.height(); y += s)
    for (int x = half < camera.width() ? half : 0; x < camera.width(); x += s) {
      core::render_pixel(view, ctx, camera, x, y, params.spp, false, scratch);
      ++out.pixels;
    }
  out.rays = scratch.stats.rays.total();
  if (beside_top > 0) charge_beside_top(beside_top, c);
}

}  // namespace

LoadEstimate estimate_load(const core::Database& db, const core::Grid& grid, const core::Camera& camera,
                           const CameraFrame& frame, const ScreenRect& extent, const EstimateParams& params) {
  if (params.subsample < 1)
    throw std::invalid_argument(fmt::format("--subsample must be >= 1, got {}", params.subsample));
  if (params.resolution < 1) throw std::invalid_argument("cost grid resolution must be >= 1");
  const auto t0 = std::chrono::steady_clock::now();
  LoadEstimate out;
  CostGrid& c = out.cost;
  c.extent = extent;
  grid_shape(extent, params.resolution, c.nx, c.ny);
  c.cost.assign(std::size_t(c.nx) * c.ny, 0.0);
  charge(db, grid, camera, frame, params, c, out);

  // The cells that were charged, padded by one cell: where that is less
  // than half the extent on an axis (a small model on a huge floor puts all
  // the work in a cell or two), charge again over it alone.
  int bx0 = c.nx, by0 = c.ny, bx1 = -1, by1 = -1;
  for (int y = 0; y < c.ny; ++y)
    for (int x = 0; x < c.nx; ++x)
      if (c.cost[std::size_t(y) * c.nx + x] > 0) {
        bx0 = std::min(bx0, x), bx1 = std::max(bx1, x);
        by0 = std::min(by0, y), by1 = std::max(by1, y);
      }
  const bool narrow_x = 2 * (bx1 - bx0 + 3) <= c.nx, narrow_y = 2 * (by1 - by0 + 3) <= c.ny;
  if (bx1 >= 0 && (narrow_x || narrow_y)) {
    const double cw = (double(extent.x1) - extent.x0) / c.nx, ch = (double(extent.y1) - extent.y0) / c.ny;
    ScreenRect work{float(extent.x0 + std::max(0, bx0 - 1) * cw), float(extent.y0 + std::max(0, by0 - 1) * ch),
                    float(extent.x0 + std::min(c.nx, bx1 + 2) * cw), float(extent.y0 + std::min(c.ny, by1 + 2) * ch)};
    work.x0 = std::max(work.x0, extent.x0), work.x1 = std::min(work.x1, extent.x1);
    work.y0 = std::max(work.y0, extent.y0), work.y1 = std::min(work.y1, extent.y1);
    if (work.x1 > work.x0 && work.y1 > work.y0) {
      c.extent = work;
      grid_shape(work, params.resolution, c.nx, c.ny);
      c.cost.assign(std::size_t(c.nx) * c.ny, 0.0);
      charge(db, grid, camera, frame, params, c, out);
      out.refined = true;
    }
  }
  // A cost cell heavier than half a region's share cannot be cut finer
  // (make_partition spreads a cell's cost evenly over it): charge again on
  // a grid four times finer, up to kMaxEstimateResolution.
  for (int res = params.resolution; params.regions > 1 && res < kMaxEstimateResolution;) {
    const double heaviest = *std::max_element(c.cost.begin(), c.cost.end());
    if (heaviest <= c.total() / (2.0 * params.regions)) break;
    res = std::min(res * 4, kMaxEstimateResolution);
    grid_shape(c.extent, res, c.nx, c.ny);
    c.cost.assign(std::size_t(c.nx) * c.ny, 0.0);
    charge(db, grid, camera, frame, params, c, out);
    out.refined = true;
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace raynode::dataflow
