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
  auto bin_cells = [&](const core::GridInfo& g, std::uint32_t first) {
    for (int z = 0; z < g.res[2]; ++z)
      for (int y = 0; y < g.res[1]; ++y)
        for (int x = 0; x < g.res[0]; ++x) {
          const core::Vec3 centre = g.cell_bounds(x, y, z).center();
          const int bx = std::clamp(int(std::floor((frame.x(centre) - e.x0) * sx)), 0, cost.nx - 1);
          const int by = std::clamp(int(std::floor((frame.y(centre) - e.y0) * sy)), 0, cost.ny - 1);
          bin[first + g.cell_index(x, y, z)] = std::uint32_t(by * cost.nx + bx);
        }
  };
  if (grid.sub_grids.empty()) {
    bin_cells(grid.info, 0);
  } else {
    for (const core::SubGrid& g : grid.sub_grids) bin_cells(g.info, g.first_entry);
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

  const std::vector<std::uint32_t> bin = cost_bins_of_cells(grid, frame, c);
  const core::DirectView base(db, grid);
  const CostView view(base, bin.data(), c.cost.data());
  const core::ShadingContext ctx = core::make_shading_context(db, params.max_depth, params.min_weight);
  core::ShadingScratch scratch;
  const int s = params.subsample, half = s / 2;
  for (int y = half < camera.height() ? half : 0; y < camera.height(); y += s)
    for (int x = half < camera.width() ? half : 0; x < camera.width(); x += s) {
      core::render_pixel(view, ctx, camera, x, y, params.spp, false, scratch);
      ++out.pixels;
    }
  out.rays = scratch.stats.rays.total();
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace raynode::dataflow
