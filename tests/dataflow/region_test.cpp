#include <doctest/doctest.h>

#include <cmath>
#include <random>

#include "core/camera.h"
#include "core/database.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/spd.h"
#include "dataflow/estimate.h"
#include "dataflow/region.h"
#include "dataflow/region_view.h"

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
