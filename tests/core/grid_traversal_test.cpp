// The 3D-DDA walk and its bookkeeping (traverse.h): rays along the grid's
// own structure (cell corners, cell planes, the grid boundary), rays that
// start inside or a hair short of a cell boundary, the early exit of the
// closest-hit walk, and mailboxing.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "core/database.h"
#include "core/direct_view.h"
#include "core/embree_scene.h"
#include "core/grid.h"
#include "core/intersect.h"
#include "core/math.h"
#include "core/scene.h"
#include "core/traverse.h"
#include "grid_test_support.h"

namespace {
using namespace raynode::core;
using namespace raynode::testing::grid;
}  // namespace

// ---------------------------------------------------------------------------
// Numerical stress: rays along the grid's own structure

TEST_CASE("grid: axis-parallel rays through cell corners and rays in cell planes hit like Embree") {
  const int res[3] = {6, 5, 7};
  const Scene s = scene_on_grid_planes(res);
  const Built b(s, forced(res[0], res[1], res[2]));
  // The added primitives lie inside the first build's bounds, so the cell
  // planes they were placed on are the planes of this grid.
  const Built without(random_scene(7, 150, 15, 8, 0.15f), forced(res[0], res[1], res[2]));
  REQUIRE(b.grid.info.bounds.lower == without.grid.info.bounds.lower);
  REQUIRE(b.grid.info.bounds.upper == without.grid.info.bounds.upper);
  RayChecker chk(b);
  fire_grid_aligned_rays(chk, 5);
  CHECK(chk.hits > chk.rays / 5);
  chk.require_clean();
}

TEST_CASE("grid: grid-aligned rays agree with brute force at the heuristic resolution too") {
  const Scene s = random_scene(9, 300, 20, 10, 0.15f);
  const Built b(s);
  CHECK(b.grid.info.cell_count() > 100);
  RayChecker chk(b);
  fire_grid_aligned_rays(chk, 6);
  CHECK(chk.hits > chk.rays / 10);
  chk.require_clean();
}

TEST_CASE("grid: rays starting exactly on the grid boundary, pointing in, out and along it") {
  const Scene s = random_scene(13, 200, 20, 10, 0.2f);
  const Built b(s, forced(5, 5, 5));
  const GridInfo& g = b.grid.info;
  RayChecker chk(b);
  Rng rng(17);
  std::size_t outward_hits = 0;
  for (int a = 0; a < 3; ++a)
    for (int side = 0; side < 2; ++side)
      for (int n = 0; n < 400; ++n) {
        Vec3 o = random_in(rng, g.bounds);
        o[a] = side ? g.bounds.upper[a] : g.bounds.lower[a];
        const float inward = side ? -1.0f : 1.0f;
        Vec3 d = random_unit(rng);
        d[a] = inward * std::fabs(d[a]);  // into the grid
        chk.check({o, d, 0.0f, kInfinity});
        d[a] = 0.0f;  // along the boundary face
        if (dot(d, d) > 0.0f) chk.check({o, d, 0.0f, kInfinity});
        d = random_unit(rng);
        d[a] = -inward * std::fabs(d[a]);  // out of the grid
        Hit h = chk.check({o, d, 0.0f, kInfinity});
        outward_hits += h.found();
      }
  // Every primitive lies inside the grid box, so a ray leaving it from its
  // boundary can hit nothing.
  CHECK(outward_hits == 0);
  chk.require_clean();
}

TEST_CASE("grid: a ray starting inside the cell that holds its hit finds it and ignores what lies behind") {
  // A 4x4x4 grid over about [0,4]^3 (anchor triangles fix the bounds).
  Scene s;
  const Vec3 lo[3] = {{0, 0, 0}, {0.1f, 0, 0}, {0, 0.1f, 0}};
  const Vec3 hi[3] = {{4, 4, 4}, {3.9f, 4, 4}, {4, 3.9f, 4}};
  s.add_polygon(lo, 3);
  s.add_polygon(hi, 3);
  // Two small walls perpendicular to x inside cell (1,1,1) = [1,2]^3.
  add_quad(s, {1.6f, 1.2f, 1.2f}, {1.6f, 1.8f, 1.2f}, {1.6f, 1.8f, 1.8f}, {1.6f, 1.2f, 1.8f});  // id 2,3
  add_quad(s, {1.1f, 1.2f, 1.2f}, {1.1f, 1.8f, 1.2f}, {1.1f, 1.8f, 1.8f}, {1.1f, 1.2f, 1.8f});  // id 4,5
  const Built b(s, forced(4, 4, 4));
  REQUIRE(b.db.primitives.size() == 6);
  const GridInfo& g = b.grid.info;
  const Bounds3 cell = g.cell_bounds(1, 1, 1);
  REQUIRE(cell.lower.x < 1.1f);
  REQUIRE(cell.upper.x > 1.6f);
  TraversalScratch scratch;
  Hit h;
  // Origin between the walls, in the same cell: the front wall at t = 0.3.
  REQUIRE(intersect_closest(b.view(), Ray{{1.3f, 1.5f, 1.5f}, {1, 0, 0}, 0.0f, kInfinity}, h, scratch));
  CHECK(h.t == doctest::Approx(0.3f).epsilon(1e-6));
  CHECK(b.db.primitives[h.primitive].shape == 2);
  // Backwards: the back wall, not the front one behind the origin.
  REQUIRE(intersect_closest(b.view(), Ray{{1.3f, 1.5f, 1.5f}, {-1, 0, 0}, 0.0f, kInfinity}, h, scratch));
  CHECK(h.t == doctest::Approx(0.2f).epsilon(1e-6));
  CHECK(b.db.primitives[h.primitive].shape == 3);
  // Past both walls within the same cell: nothing ahead.
  CHECK_FALSE(intersect_closest(b.view(), Ray{{1.7f, 1.5f, 1.5f}, {1, 0, 0}, 0.0f, kInfinity}, h, scratch));
  // The hit is honoured only in (tmin, tmax).
  CHECK_FALSE(intersect_closest(b.view(), Ray{{1.3f, 1.5f, 1.5f}, {1, 0, 0}, 0.0f, 0.29f}, h, scratch));
  CHECK_FALSE(intersect_closest(b.view(), Ray{{1.3f, 1.5f, 1.5f}, {1, 0, 0}, 0.31f, kInfinity}, h, scratch));
  CHECK_FALSE(intersect_any(b.view(), Ray{{1.3f, 1.5f, 1.5f}, {1, 0, 0}, 0.0f, 0.29f}, scratch));
  CHECK(intersect_any(b.view(), Ray{{1.3f, 1.5f, 1.5f}, {1, 0, 0}, 0.0f, 0.31f}, scratch));
}

TEST_CASE("grid: a ray starting a hair short of a cell boundary finds the primitive between it and the boundary") {
  // Cells of about 1 over [0,4]^3; small walls perpendicular to x lie within
  // 5e-4 of a cell plane, on the side of the ray's origin only (the cell box
  // inflation is 1e-4 of a cell).
  Scene s;
  const Vec3 lo[3] = {{0, 0, 0}, {0.1f, 0, 0}, {0, 0.1f, 0}};
  const Vec3 hi[3] = {{4, 4, 4}, {3.9f, 4, 4}, {4, 3.9f, 4}};
  s.add_polygon(lo, 3);
  s.add_polygon(hi, 3);
  const Built probe(s, forced(4, 4, 4));
  const GridInfo& g = probe.grid.info;
  const float plane_hi = grid_plane(g, 0, 2), plane_lo = grid_plane(g, 0, 1);  // cell 1 in x: [plane_lo, plane_hi]
  const float before = plane_hi - 5e-4f, wall_hi = plane_hi - 2.5e-4f;
  const float after = plane_lo + 5e-4f, wall_lo = plane_lo + 2.5e-4f;
  add_quad(s, {wall_hi, 2.2f, 2.2f}, {wall_hi, 2.8f, 2.2f}, {wall_hi, 2.8f, 2.8f}, {wall_hi, 2.2f, 2.8f});
  add_quad(s, {wall_lo, 2.2f, 2.2f}, {wall_lo, 2.8f, 2.2f}, {wall_lo, 2.8f, 2.8f}, {wall_lo, 2.2f, 2.8f});
  const Built b(s, forced(4, 4, 4));
  REQUIRE(b.grid.info.bounds.lower == g.bounds.lower);
  REQUIRE(b.grid.info.bounds.upper == g.bounds.upper);
  TraversalScratch scratch;
  Hit h;
  for (const Vec3& d : {Vec3{1, 0, 0}, Vec3{1, 0.01f, -0.02f}}) {
    const Ray up{{before, 2.5f, 2.5f}, d, 0.0f, kInfinity};
    REQUIRE(intersect_closest(b.view(), up, h, scratch));
    CHECK(b.db.primitives[h.primitive].shape == 2);
    CHECK(h.t == brute_closest(b, up).t);
    const Ray down{{after, 2.5f, 2.5f}, -d, 0.0f, kInfinity};
    REQUIRE(intersect_closest(b.view(), down, h, scratch));
    CHECK(b.db.primitives[h.primitive].shape == 3);
    CHECK(h.t == brute_closest(b, down).t);
  }
}

TEST_CASE("grid: a large primitive hit beyond the current cell does not hide a nearer one in a later cell") {
  // A long slanted triangle spans all eight cells along x; the ray y = 0.75
  // meets it at x = 7.47 (cell 7) after testing it in cell 0. A small wall at x = 4.5
  // (cell 4 only) is nearer and must win.
  Scene s;
  const Vec3 slant[3] = {{0, -1, -1}, {8, 0.875f, -1}, {8, 0.875f, 1}};  // y = -1 + 0.234375 x
  s.add_polygon(slant, 3);
  add_quad(s, {4.5f, 0.5f, -0.5f}, {4.5f, 1.0f, -0.5f}, {4.5f, 1.0f, 0.5f}, {4.5f, 0.5f, 0.5f});
  const Vec3 anchor[3] = {{0, 1, 1}, {8, 1, 1}, {8, 1, 0.9f}};
  s.add_polygon(anchor, 3);
  const Built b(s, forced(8, 1, 1));
  const Ray ray{{-1, 0.75f, 0}, {1, 0, 0}, 0.0f, kInfinity};
  const Hit brute = brute_closest(b, ray);
  REQUIRE(brute.found());
  REQUIRE(b.db.primitives[brute.primitive].shape == 1);
  TraversalScratch scratch;
  Hit h;
  REQUIRE(intersect_closest(b.view(), ray, h, scratch));
  CHECK(b.db.primitives[h.primitive].shape == 1);
  CHECK(h.t == brute.t);
  CHECK(h.t == doctest::Approx(5.5f));
  // Without the wall the slanted triangle is found at its far cell.
  Scene s2;
  s2.add_polygon(slant, 3);
  s2.add_polygon(anchor, 3);
  const Built b2(s2, forced(8, 1, 1));
  REQUIRE(intersect_closest(b2.view(), ray, h, scratch));
  CHECK(h.primitive == 0);
  CHECK(h.t == brute_closest(b2, ray).t);
  CHECK(h.t > 7.0f);
}

TEST_CASE("grid: an exact tie in t goes to the lowest primitive id over every grid, packed or not") {
  // The ray o = (0, 0, 4), d = (1, 0, -1) meets a floor triangle (id 0) and
  // a wall triangle in the plane x = 4 (id 1) at the same point (4, 0, 0),
  // t = 4 exactly for both (small dyadic coordinates: every step of the
  // watertight test is exact). The wall reaches up into cells the ray
  // crosses before the floor's, so a grid may test it first: the hit must
  // still be the floor's, as brute force (ids in order, ties kept) finds.
  Scene s;
  const Vec3 floor_tri[3] = {{3, -1, 0}, {6, -1, 0}, {3, 2, 0}};
  const Vec3 wall[3] = {{4, -1, -1}, {4, -1, 3}, {4, 2, 1}};
  s.add_polygon(floor_tri, 3);
  s.add_polygon(wall, 3);
  const Ray ray{{0, 0, 4}, {1, 0, -1}, 0.0f, kInfinity};
  Failures wrong;
  int grids = 0;
  auto check = [&](const Built& b, const std::string& what) {
    const Hit brute = brute_closest(b, ray);
    REQUIRE(brute.found());
    REQUIRE(brute.primitive == 0);
    REQUIRE(brute.t == 4.0f);
    TraversalScratch scratch;
    for (const bool packed : {false, true}) {
      Hit h;
      const bool found = packed ? intersect_closest(b.packed_view(), ray, h, scratch)
                                : intersect_closest(b.view(), ray, h, scratch);
      ++grids;
      if (!found || h.primitive != brute.primitive || h.t != brute.t || h.u != brute.u || h.v != brute.v)
        wrong.add(what + (packed ? " packed" : "") + ": " + str(h) + " against " + str(brute));
    }
  };
  for (int rx = 1; rx <= 8; ++rx)
    for (int rz = 1; rz <= 8; ++rz) check(Built(s, forced(rx, 1, rz)), "uniform " + std::to_string(rx) + "x1x" + std::to_string(rz));
  for (const float weight : {1.0f, kPackedTriangleWeight}) {
    GridParams adaptive;
    adaptive.kind = GridKind::kAdaptive;
    adaptive.triangle_weight = weight;
    check(Built(s, adaptive), "adaptive, triangle weight " + std::to_string(weight));
  }
  INFO(wrong.count << " of " << grids << " grids took another hit:" << wrong.first);
  CHECK(wrong.count == 0);
}

// ---------------------------------------------------------------------------
// Traversal work: mailboxing and early exit

TEST_CASE("grid: mailboxing tests a large triangle once per ray however many of its cells the ray crosses") {
  // The triangle spans the plane z = x + y over [0,1]^3; the ray runs
  // parallel to it, just above, through a long chain of cells that list it.
  Scene s;
  const Vec3 tri[3] = {{0, 0, 0}, {1, 0, 1}, {0, 1, 1}};
  s.add_polygon(tri, 3);
  const Built b(s, forced(16, 16, 16));
  const Ray ray{{-0.5f, 0.05f, -0.45f + 1e-3f}, {1, 0, 1}, 0.0f, kInfinity};
  TraversalScratch scratch;
  Hit h;
  CHECK_FALSE(intersect_closest(b.view(), ray, h, scratch));
  CHECK(scratch.stats.rays == 1);
  CHECK(scratch.stats.cells_visited >= 16);
  CHECK(scratch.stats.triangle_tests == 1);
  CHECK(scratch.stats.mailbox_skips >= 8);
  // The mailbox is per ray: the next ray tests the triangle again.
  CHECK_FALSE(intersect_any(b.view(), ray, scratch));
  CHECK(scratch.stats.triangle_tests == 2);
  // A ray that does hit it far along still tests it once.
  TraversalScratch s2;
  // 0.013 above the plane, closing in at 0.01 per unit: hits at x = 0.8.
  const Ray hitting{{-0.5f, 0.05f, -0.45f + 0.013f}, {1, 0, 0.99f}, 0.0f, kInfinity};
  REQUIRE(intersect_closest(b.view(), hitting, h, s2));
  CHECK(h.t == brute_closest(b, hitting).t);
  CHECK(s2.stats.triangle_tests == 1);
  CHECK(s2.stats.mailbox_skips > 0);
}

TEST_CASE("grid: the walk stops early when a near primitive is hit") {
  // A far wall at x = 10 and, in the second scene, a small near wall at x = 0.5;
  // anchors keep both grids' bounds identical.
  auto make = [](bool near) {
    Scene s;
    add_quad(s, {10, -1, -1}, {10, 1, -1}, {10, 1, 1}, {10, -1, 1});
    const Vec3 anchor[3] = {{0, -1, -1}, {0, -0.95f, -1}, {0, -1, -0.95f}};
    s.add_polygon(anchor, 3);
    if (near) add_quad(s, {0.5f, -0.2f, -0.2f}, {0.5f, 0.2f, -0.2f}, {0.5f, 0.2f, 0.2f}, {0.5f, -0.2f, 0.2f});
    return s;
  };
  // Cell by cell (no empty-space jumps), so that the walk's length is the
  // number of cells up to the hit.
  GridParams gp = forced(64, 4, 4);
  gp.skip_empty = false;
  const Built with_near(make(true), gp);
  const Built far_only(make(false), gp);
  REQUIRE(with_near.grid.info.bounds.lower == far_only.grid.info.bounds.lower);
  REQUIRE(with_near.grid.info.bounds.upper == far_only.grid.info.bounds.upper);
  const Ray ray{{-1, 0.1f, 0.05f}, {1, 0, 0}, 0.0f, kInfinity};
  TraversalScratch a, b;
  Hit ha, hb;
  REQUIRE(intersect_closest(with_near.view(), ray, ha, a));
  REQUIRE(intersect_closest(far_only.view(), ray, hb, b));
  CHECK(ha.t == doctest::Approx(1.5f));
  CHECK(hb.t == doctest::Approx(11.0f));
  CHECK(a.stats.cells_visited * 8 < b.stats.cells_visited);
  CHECK(b.stats.cells_visited >= 60);
  // The any-hit query stops early too.
  TraversalScratch c;
  CHECK(intersect_any(with_near.view(), ray, c));
  CHECK(c.stats.cells_visited * 8 < b.stats.cells_visited);
}

// ---------------------------------------------------------------------------
// Empty-space jumps (Grid::empty_distance)

TEST_CASE("grid: empty-space distances are the Chebyshev distance to the nearest non-empty cell") {
  for (const std::uint64_t seed : {3u, 4u}) {
    const Built b(random_scene(seed, 12, 2, 1, 0.05f), forced(13, 9, 7));
    const GridInfo& g = b.grid.info;
    REQUIRE(b.grid.empty_distance.size() == g.cell_count());
    std::size_t nonempty = 0, far = 0;
    for (int z = 0; z < g.res[2]; ++z)
      for (int y = 0; y < g.res[1]; ++y)
        for (int x = 0; x < g.res[0]; ++x) {
          const std::uint32_t c = g.cell_index(x, y, z);
          int expect = 255;
          for (int qz = 0; qz < g.res[2]; ++qz)
            for (int qy = 0; qy < g.res[1]; ++qy)
              for (int qx = 0; qx < g.res[0]; ++qx) {
                const std::uint32_t q = g.cell_index(qx, qy, qz);
                if (b.grid.cell_start[q] == b.grid.cell_start[q + 1]) continue;
                expect = std::min(expect, std::max({std::abs(qx - x), std::abs(qy - y), std::abs(qz - z)}));
              }
          CAPTURE(x);
          CAPTURE(y);
          CAPTURE(z);
          REQUIRE(int(b.grid.empty_distance[c]) == expect);
          nonempty += expect == 0;
          far += expect >= 3;
        }
    // The scene leaves room for real jumps.
    CHECK(nonempty > 0);
    CHECK(far > 0);
  }
  // Switched off: 0 and 1 only. No primitives: the cap everywhere.
  GridParams off = forced(13, 9, 7);
  off.skip_empty = false;
  const Built plain(random_scene(3, 12, 2, 1, 0.05f), off);
  for (std::uint32_t c = 0; c < plain.grid.info.cell_count(); ++c)
    REQUIRE(plain.grid.empty_distance[c] == (plain.grid.cell_start[c] == plain.grid.cell_start[c + 1] ? 1 : 0));
  const Built none(Scene{}, forced(5, 5, 5));
  for (const std::uint8_t d : none.grid.empty_distance) REQUIRE(d == kMaxEmptyDistance);
}

namespace {

// Fires `rays` through a grid with jumps and the same grid without, and
// requires the same answers bit for bit; returns the cells each visited.
struct JumpComparison {
  JumpComparison(const Built& with_jumps, const Built& cell_by_cell) : jumps(with_jumps), plain(cell_by_cell) {}
  const Built& jumps;
  const Built& plain;
  TraversalScratch sj, sp;
  std::size_t rays = 0, hits = 0;

  void fire(const Ray& ray) {
    Hit hj, hp;
    const bool fj = intersect_closest(jumps.view(), ray, hj, sj);
    const bool fp = intersect_closest(plain.view(), ray, hp, sp);
    INFO(str(ray));
    REQUIRE(fj == fp);
    REQUIRE(hj.primitive == hp.primitive);
    REQUIRE(std::memcmp(&hj.t, &hp.t, sizeof(float)) == 0);
    REQUIRE(intersect_any(jumps.view(), ray, sj) == intersect_any(plain.view(), ray, sp));
    ++rays;
    hits += fj;
  }
};

}  // namespace

TEST_CASE("grid: empty-space jumps find the cell-by-cell walk's hits, bit for bit, in fewer cells") {
  // Sparse scenes at a fine resolution: long empty runs between small objects.
  for (const std::uint64_t seed : {11u, 12u, 13u}) {
    CAPTURE(seed);
    const Scene s = random_scene(seed, 30, 3, 2, 0.04f);
    GridParams on = forced(40, 33, 27), off = on;
    off.skip_empty = false;
    const Built jumps(s, on), plain(s, off);
    REQUIRE(jumps.grid.info.bounds.lower == plain.grid.info.bounds.lower);
    REQUIRE(jumps.grid.cell_primitives == plain.grid.cell_primitives);
    JumpComparison cmp(jumps, plain);
    const GridInfo& g = jumps.grid.info;
    Rng rng(seed);
    const Bounds3 around = grown(g.bounds, 0.3f);
    // Random rays from outside, inside, and aimed at primitives; shadow-ray
    // segments that end in empty space.
    for (int i = 0; i < 3000; ++i) {
      const Vec3 o = random_in(rng, i % 2 ? around : g.bounds);
      cmp.fire(Ray{o, random_unit(rng), 0.0f, kInfinity});
      const Primitive& p = jumps.db.primitives[rng() % jumps.db.primitives.size()];
      cmp.fire(Ray{o, normalize(centre_of(p) - o), 0.0f, kInfinity});
      cmp.fire(Ray{o, random_unit(rng), 0.0f, uniform(rng, 0.05f, 2.0f)});
    }
    // Rays along cell planes, through cell edges and grid vertices, axis
    // parallel and diagonal: where a jump's exit point lies on cell boundaries.
    for (int i = 0; i < 3000; ++i) {
      const int a = int(rng() % 3), b2 = (a + 1) % 3;
      Vec3 o = random_in(rng, around);
      o[a] = grid_plane(g, a, int(rng() % (g.res[a] + 1)));
      if (i % 2) o[b2] = grid_plane(g, b2, int(rng() % (g.res[b2] + 1)));
      Vec3 d = random_unit(rng);
      d[a] = 0;
      if (i % 3 == 0) d[b2] = 0;
      if (i % 5 == 0) d = Vec3{1, 1, 1} * (rng() % 2 ? 1.0f : -1.0f);
      if (i % 7 == 0) {
        d = {0, 0, 0};
        d[int(rng() % 3)] = rng() % 2 ? 1.0f : -1.0f;
      }
      if (length(d) < 1e-3f) continue;
      cmp.fire(Ray{o, normalize(d), 0.0f, kInfinity});
    }
    CHECK(cmp.hits > cmp.rays / 10);
    CHECK(cmp.sj.stats.cells_visited * 2 < cmp.sp.stats.cells_visited);
    CHECK(cmp.sj.stats.empty_jumps > 0);
    CHECK(cmp.sp.stats.empty_jumps == 0);
  }
}

TEST_CASE("grid: a jump never passes a primitive in the cell just beyond the empty cube") {
  // One small triangle per cell at the end of a long empty corridor, hit by
  // rays along the corridor at many slopes: each jump ends next to it.
  GridParams on = forced(64, 8, 8), off = on;
  off.skip_empty = false;
  Scene s;
  add_quad(s, {-1, -1, -1}, {-0.99f, -1, -1}, {-0.99f, -0.99f, -1}, {-1, -0.99f, -1});  // anchors the box
  add_quad(s, {1, 1, 1}, {0.99f, 1, 1}, {0.99f, 0.99f, 1}, {1, 0.99f, 1});
  const Built probe(s, on);
  const GridInfo& g = probe.grid.info;
  for (int i = 5; i < 64; i += 12) {  // empty runs of 11 cells: distances up to 6
    const float x = grid_plane(g, 0, i) + 0.5f * g.cell_size.x;
    add_quad(s, {x, -0.2f, -0.2f}, {x, 0.2f, -0.2f}, {x, 0.2f, 0.2f}, {x, -0.2f, 0.2f});
  }
  const Built jumps(s, on), plain(s, off);
  REQUIRE(jumps.grid.info.bounds.lower == g.bounds.lower);
  JumpComparison cmp(jumps, plain);
  Rng rng(5);
  for (int i = 0; i < 2000; ++i) {
    const float x0 = grid_plane(g, 0, int(rng() % 64));
    const Vec3 o{x0, uniform(rng, -0.3f, 0.3f), uniform(rng, -0.3f, 0.3f)};
    const Vec3 d = normalize(Vec3{rng() % 2 ? 1.0f : -1.0f, uniform(rng, -0.05f, 0.05f), uniform(rng, -0.05f, 0.05f)});
    cmp.fire(Ray{o, d, 0.0f, kInfinity});
  }
  CHECK(cmp.hits > cmp.rays / 3);
  CHECK(cmp.sj.stats.empty_jumps > 0);
  CHECK(cmp.sj.stats.cells_visited < cmp.sp.stats.cells_visited);
}

TEST_CASE("grid: rays with a direction component near 0 (huge or infinite reciprocal) walk like brute force") {
  // A component of 1e-30 or a denormal 1e-40 overflows the parameter of
  // that axis's boundaries: the walk must neither step along it nor take
  // a NaN for the next boundary, from inside the grid, from outside it and
  // from a cell plane, in the uniform and the adaptive grid.
  const Scene s = random_scene(21, 300, 20, 10, 0.15f);
  for (const bool adaptive : {false, true}) {
    CAPTURE(adaptive);
    GridParams gp;
    if (adaptive) gp.kind = GridKind::kAdaptive;
    const Built b(s, gp);
    RayChecker chk(b);
    Rng rng(22);
    const Bounds3 box = grown(b.db.bounds, 0.2f);
    const GridInfo& g = b.grid.info;
    for (int i = 0; i < 3000; ++i) {
      Vec3 o = random_in(rng, box);
      const int a = i % 3;
      if (i % 4 == 0) o[a] = g.bounds.lower[a] + float(i % g.res[a]) * g.cell_size[a];  // on a cell plane
      Vec3 d = random_unit(rng);
      const float tiny[3] = {1e-30f, 1e-40f, -1e-40f};
      d[a] = tiny[(i / 3) % 3];
      if (i % 5 == 0) d[(a + 1) % 3] = 0.0f;  // and one axis still
      if (length(d) == 0.0f) continue;
      chk.check(Ray{o, d, 0.0f, kInfinity});
    }
    CHECK(chk.hits > 300);
    chk.require_clean();
  }
}
