#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "core/camera.h"
#include "core/database.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/scene.h"
#include "core/spd.h"
#include "dataflow/estimate.h"
#include "dataflow/region.h"
#include "dataflow/region_view.h"
#include "test_grid_params.h"

using namespace raynode;
using namespace raynode::dataflow;

namespace {

CameraFrame test_frame() {
  core::View v;
  v.from = {3, -4, 2};
  v.at = {0, 0, 0};
  v.up = {0, 0, 1};
  v.angle = 45;
  return CameraFrame::of(v);
}

CostGrid random_cost(int nx, int ny, unsigned seed) {
  CostGrid c;
  c.extent = {-2, -1, 3, 2};
  c.nx = nx, c.ny = ny;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  for (int i = 0; i < nx * ny; ++i) c.cost.push_back(u(rng) < 0.3 ? 0.0 : u(rng) * u(rng) * 100);
  return c;
}

}  // namespace

TEST_CASE("region: every point of the extent lies in exactly one region, the one locate() names") {
  const CameraFrame f = test_frame();
  for (std::uint32_t n : {1u, 2u, 3u, 5u, 7u, 12u, 32u, 64u}) {
    CAPTURE(n);
    const Partition p = make_partition(f, random_cost(40, 30, n), n);
    REQUIRE(p.region_count() == n);
    const RegionMap map = p.map();
    std::mt19937 rng(n);
    std::uniform_real_distribution<float> ux(-3, 4), uy(-2, 3), ud(-1, 1);
    for (int i = 0; i < 2000; ++i) {
      const float x = ux(rng), y = uy(rng);
      int inside = 0;
      std::uint32_t which = 0;
      for (std::uint32_t r = 0; r < n; ++r) {
        const ScreenRect& b = p.rects[r];
        if (x >= b.x0 && x < b.x1 && y >= b.y0 && y < b.y1) ++inside, which = r;
      }
      CHECK(inside == 1);
      CHECK(map.locate(x, y, ud(rng), ud(rng)) == which);
    }
    // The finite rectangles tile the extent: their areas add up to it.
    double area = 0;
    for (const ScreenRect& r : p.finite) area += double(r.x1 - r.x0) * double(r.y1 - r.y0);
    const double ext = double(p.extent.x1 - p.extent.x0) * double(p.extent.y1 - p.extent.y0);
    CHECK(area == doctest::Approx(ext).epsilon(1e-5));
  }
}

TEST_CASE("region: balanced cuts give every region its proportional share of the cost") {
  const CameraFrame f = test_frame();
  for (std::uint32_t n : {2u, 3u, 4u, 7u, 16u, 33u}) {
    CAPTURE(n);
    const CostGrid c = random_cost(64, 48, 7 * n);
    const Partition p = make_partition(f, c, n);
    const double total = c.total();
    for (std::uint32_t r = 0; r < n; ++r) {
      CAPTURE(r);
      // Cuts interpolate inside a cell, so each share is exact up to rounding.
      CHECK(cost_in(c, p.finite[r]) == doctest::Approx(total / n).epsilon(1e-3));
    }
  }
}

TEST_CASE("region: equal partition gives regions of equal area") {
  const CameraFrame f = test_frame();
  const CostGrid c = uniform_cost(ScreenRect{-2, -1, 3, 2}, 64);
  for (std::uint32_t n : {3u, 8u, 12u}) {
    const Partition p = make_partition(f, c, n);
    const double ext = 5.0 * 3.0;
    for (const ScreenRect& r : p.finite)
      CHECK(double(r.x1 - r.x0) * double(r.y1 - r.y0) == doctest::Approx(ext / n).epsilon(1e-4));
  }
}

TEST_CASE("region: walking a ray visits regions whose intervals chain without gap or overlap") {
  const CameraFrame f = test_frame();
  const Partition p = make_partition(f, random_cost(32, 32, 3), 12);
  const RegionMap map = p.map();
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1, 1);
  for (int i = 0; i < 3000; ++i) {
    ScreenRay r{u(rng) * 3, u(rng), u(rng) * 2, u(rng)};
    if (i % 10 == 0) r.dx = 0;  // parallel to the x cuts
    if (i % 10 == 1) r.dy = 0;
    if (i % 17 == 0) r.x0 = p.tree[0].cut;  // starts on the first cut
    float t = 0;
    std::uint32_t region = map.region_at(r, t);
    int steps = 0;
    for (;;) {
      // The region holds the ray's point at the middle of its interval.
      std::uint32_t next = region;
      const float t_exit = map.exit_region(region, r, t, next);
      REQUIRE(t_exit >= t);
      if (!(t_exit < core::kInfinity)) break;
      REQUIRE(next != region);
      if (t_exit > t) {
        const float tm = 0.5f * (t + t_exit);
        const ScreenRect& b = p.rects[region];
        const float x = r.x0 + tm * r.dx, y = r.y0 + tm * r.dy;
        CHECK(x >= b.x0 - 1e-4f);
        CHECK(x <= b.x1 + 1e-4f);
        CHECK(y >= b.y0 - 1e-4f);
        CHECK(y <= b.y1 + 1e-4f);
      }
      t = t_exit;
      region = next;
      REQUIRE(++steps <= 64);
    }
  }
}

TEST_CASE("region: region databases hold every primitive at least once, shared ones flagged") {
  const core::Database db = core::make_database(core::make_spd_scene(core::SpdParams{"rings", 1, 0}));
  const core::Grid grid = core::build_grid(db);
  const core::View view = core::render_view(db);
  const core::Camera cam(view, 48, 32);
  const CameraFrame f = CameraFrame::of(view);
  const ScreenRect e = screen_extent(f, db.bounds);
  const LoadEstimate est = estimate_load(db, grid, cam, f, e, EstimateParams{});
  CHECK(est.pixels == 6u * 4u);
  CHECK(est.cost.total() > 0);
  const Partition p = make_partition(f, est.cost, 6);
  const std::vector<RegionDatabase> rds = make_region_databases(db, p);
  REQUIRE(rds.size() == 6);
  std::vector<int> seen(db.primitives.size(), 0);
  std::size_t held = 0;
  for (const RegionDatabase& rd : rds) {
    held += rd.global.size();
    for (std::size_t i = 0; i < rd.global.size(); ++i) {
      ++seen[rd.global[i]];
      CHECK(rd.db.primitives[i].shape == db.primitives[rd.global[i]].shape);
    }
  }
  for (std::size_t i = 0; i < seen.size(); ++i) CHECK(seen[i] >= 1);
  CHECK(held > db.primitives.size());  // some primitives straddle a cut
  for (const RegionDatabase& rd : rds)
    for (std::size_t i = 0; i < rd.global.size(); ++i) CHECK((rd.shared[i] == 1) == (seen[rd.global[i]] > 1));
}

TEST_CASE("region: every leaf of an adaptive grid is binned inside its own box's screen footprint") {
  // A coarse top grid and sub-grids from 4 primitives on: tetra:3 gets sub-grids two levels deep.
  const core::Database db = core::make_database(core::make_spd_scene(core::SpdParams{"tetra", 3, 0}));
  const core::Grid grid = core::build_grid(db, raynode::testing::small_scene_sub_grids(4, true));
  REQUIRE(grid.sub_grid_count() > 0);
  REQUIRE(grid.depth() >= 2);
  const CameraFrame f = CameraFrame::of(core::render_view(db));
  CostGrid c = uniform_cost(screen_extent(f, db.bounds), 64);
  const std::vector<std::uint32_t> bin = cost_bins_of_cells(grid, f, c);
  REQUIRE(bin.size() == grid.leaf_cells());
  // Bin range of a world box: its corners' projections, clamped as the bins are.
  auto bin_range = [&](const core::Bounds3& b, int& x0, int& y0, int& x1, int& y1) {
    x0 = y0 = 1 << 30, x1 = y1 = -1;
    const double sx = c.nx / (double(c.extent.x1) - c.extent.x0), sy = c.ny / (double(c.extent.y1) - c.extent.y0);
    for (int i = 0; i < 8; ++i) {
      const core::Vec3 p{(i & 1) ? b.upper.x : b.lower.x, (i & 2) ? b.upper.y : b.lower.y,
                         (i & 4) ? b.upper.z : b.lower.z};
      const int bx = std::clamp(int(std::floor((f.x(p) - c.extent.x0) * sx)), 0, c.nx - 1);
      const int by = std::clamp(int(std::floor((f.y(p) - c.extent.y0) * sy)), 0, c.ny - 1);
      x0 = std::min(x0, bx), x1 = std::max(x1, bx), y0 = std::min(y0, by), y1 = std::max(y1, by);
    }
  };
  std::size_t checked = 0, deep = 0;
  std::vector<int> seen(grid.leaf_cells(), 0);
  for (const core::SubGrid& g : grid.sub_grids)
    for (int z = 0; z < g.info.res[2]; ++z)
      for (int y = 0; y < g.info.res[1]; ++y)
        for (int x = 0; x < g.info.res[0]; ++x) {
          const std::uint32_t leaf = g.first_entry + g.info.cell_index(x, y, z);
          REQUIRE(leaf < bin.size());
          ++seen[leaf];
          int x0, y0, x1, y1;
          bin_range(g.info.cell_bounds(x, y, z), x0, y0, x1, y1);
          const int bx = int(bin[leaf] % std::uint32_t(c.nx)), by = int(bin[leaf] / std::uint32_t(c.nx));
          CAPTURE(leaf);
          CAPTURE(g.level);
          CHECK(bin[leaf] < std::uint32_t(c.nx * c.ny));
          CHECK(bx >= x0);
          CHECK(bx <= x1);
          CHECK(by >= y0);
          CHECK(by <= y1);
          ++checked;
          deep += g.level >= 2;
        }
  CHECK(checked == grid.leaf_cells());
  CHECK(deep > 0);
  for (int s : seen) CHECK(s == 1);
}

TEST_CASE("region: the estimate over an adaptive grid traces the uniform grid's rays and charges where the mesh is") {
  // A small mesh on a floor 100x its size; sub-grids from 8 primitives on.
  core::Scene s = core::make_spd_scene(core::SpdParams{"teapot", 3, 0});
  const core::Bounds3 mb = core::make_database(s).bounds;
  const core::Vec3 mc = mb.center();
  const float half = 50.0f * std::max(mb.upper.x - mb.lower.x, mb.upper.y - mb.lower.y);
  const float z = mb.lower.z - 0.01f * (mb.upper.z - mb.lower.z);
  const core::Vec3 quad[4] = {{mc.x - half, mc.y - half, z}, {mc.x + half, mc.y - half, z},
                              {mc.x + half, mc.y + half, z}, {mc.x - half, mc.y + half, z}};
  s.add_polygon(quad, 4);
  const core::Database db = core::make_database(s);
  // The floor beside the top grid (its work spread under its footprint) or in it.
  for (const bool beside_top : {true, false}) {
  CAPTURE(beside_top);
  core::GridParams gp = raynode::testing::small_scene_sub_grids(8, false);
  gp.large_beside_top = beside_top;
  const core::Grid adaptive = core::build_grid(db, gp);
  REQUIRE(adaptive.sub_grid_count() > 0);
  CHECK(adaptive.sub_grids[0].large_list == beside_top);
  const core::Grid uniform = core::build_grid(db);
  const core::View view = core::render_view(db);
  const core::Camera cam(view, 64, 64);
  const CameraFrame f = CameraFrame::of(view);
  const ScreenRect e = screen_extent(f, db.bounds);
  EstimateParams ep;
  ep.subsample = 2;
  const LoadEstimate ea = estimate_load(db, adaptive, cam, f, e, ep);
  const LoadEstimate eu = estimate_load(db, uniform, cam, f, e, ep);
  // The same hits, so the same secondary rays (a walk that skipped the
  // sub-grids would miss the mesh and spawn fewer).
  CHECK(ea.pixels == eu.pixels);
  CHECK(ea.rays == eu.rays);
  CHECK(ea.rays > ea.pixels);
  // (The floor in the grids, both charge its cells where rays meet them,
  // over the same rectangle; beside the top grid its work follows the
  // mesh's, and the estimate may narrow to the mesh.)
  if (!beside_top) REQUIRE(ea.cost.cost.size() == eu.cost.cost.size());
  for (double v : ea.cost.cost) CHECK(v >= 0.0);
  // The mesh's screen footprint (the bins under its box, over the extent
  // each estimate charged) holds the busiest bin.
  for (const LoadEstimate* est : {&ea, &eu}) {
    const ScreenRect& ce = est->cost.extent;
    const double sx = est->cost.nx / (double(ce.x1) - ce.x0), sy = est->cost.ny / (double(ce.y1) - ce.y0);
    int x0 = est->cost.nx, y0 = est->cost.ny, x1 = -1, y1 = -1;
    for (int i = 0; i < 8; ++i) {
      const core::Vec3 p{(i & 1) ? mb.upper.x : mb.lower.x, (i & 2) ? mb.upper.y : mb.lower.y,
                         (i & 4) ? mb.upper.z : mb.lower.z};
      const int bx = std::clamp(int(std::floor((f.x(p) - ce.x0) * sx)), 0, est->cost.nx - 1);
      const int by = std::clamp(int(std::floor((f.y(p) - ce.y0) * sy)), 0, est->cost.ny - 1);
      x0 = std::min(x0, bx), x1 = std::max(x1, bx), y0 = std::min(y0, by), y1 = std::max(y1, by);
    }
    const auto top = std::max_element(est->cost.cost.begin(), est->cost.cost.end()) - est->cost.cost.begin();
    const int bx = int(top % est->cost.nx), by = int(top / est->cost.nx);
    CHECK(bx >= x0);
    CHECK(bx <= x1);
    CHECK(by >= y0);
    CHECK(by <= y1);
  }
  // Balanced cuts on the adaptive estimate: the requested regions, each its share.
  const Partition p = make_partition(f, ea.cost, 8);
  CHECK(p.region_count() == 8u);
  }
}

TEST_CASE("region: where no ray's walk enters the top grid, the large primitives' work beside it is spread evenly") {
  // A small mesh on a floor 100x its size, seen from straight above a patch
  // of floor far from it, with no light (no shadow ray) and rays reflected
  // straight up: every ray tests only the floor, beside the top grid.
  core::Scene s = core::make_spd_scene(core::SpdParams{"teapot", 3, 0});
  s.lights.clear();
  const core::Bounds3 mb = core::make_database(s).bounds;
  const core::Vec3 mc = mb.center();
  const float size = std::max(mb.upper.x - mb.lower.x, mb.upper.y - mb.lower.y);
  const float half = 50.0f * size;
  const float z = mb.lower.z - 0.01f * (mb.upper.z - mb.lower.z);
  const core::Vec3 quad[4] = {{mc.x - half, mc.y - half, z}, {mc.x + half, mc.y - half, z},
                              {mc.x + half, mc.y + half, z}, {mc.x - half, mc.y + half, z}};
  s.add_polygon(quad, 4);
  const core::Database db = core::make_database(s);
  const core::Grid grid = core::build_grid(db, raynode::testing::small_scene_sub_grids(8, false));
  REQUIRE(grid.sub_grids[0].large_list);  // the floor beside the top grid
  core::View view;
  const core::Vec3 spot{mc.x + 0.4f * half, mc.y + 0.4f * half, z};
  view.from = spot + core::Vec3{0, 0, 3.0f * size};
  view.at = spot;
  view.up = {0, 1, 0};
  const core::Camera cam(view, 32, 32);
  const CameraFrame f = CameraFrame::of(view);
  EstimateParams ep;
  ep.subsample = 2;
  const LoadEstimate est = estimate_load(db, grid, cam, f, screen_extent(f, db.bounds), ep);
  REQUIRE(!est.cost.cost.empty());
  CHECK(est.cost.total() > 0.0);  // the floor's tests are charged, though no cell of the top grid was
  const auto [lo, hi] = std::minmax_element(est.cost.cost.begin(), est.cost.cost.end());
  CHECK(*lo > 0.0);
  CHECK(*hi == doctest::Approx(*lo).epsilon(1e-12));
}
