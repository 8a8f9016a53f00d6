// The adaptive grid (core/grid.h: a top grid whose dense cells hold their
// own sub-grids): its hits equal brute force's bit for bit and Embree's on
// SPD scenes, a small mesh on a huge floor, random soups and degenerate
// databases; its images equal the uniform grid's; its per-axis resolutions
// never give a thin-but-populated axis one cell. No timing here (bench accel).
#include <doctest/doctest.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iomanip>
#include <string>
#include <vector>

#include "core/database.h"
#include "core/direct_view.h"
#include "core/embree_scene.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/scene.h"
#include "core/scene_source.h"
#include "core/traverse.h"
#include "core/validate.h"
#include "grid_test_support.h"
#include "test_grid_params.h"

namespace {
using namespace raynode::core;
using namespace raynode::testing::grid;

GridParams adaptive() {
  GridParams p;
  p.kind = GridKind::kAdaptive;
  return p;
}

// The adaptive grid with a coarse top grid and sub-grids from 4 primitives
// on, wherever a ray meets no more references in them than in the leaf:
// small scenes then get sub-grids two levels deep.
GridParams adaptive_deep() { return raynode::testing::small_scene_sub_grids(4, true); }

// A small random mesh around the origin (size ~2) on a square floor of
// half-width `floor` at z = -1.5.
Scene mesh_on_floor(std::uint64_t seed, int triangles, float floor) {
  Scene s = random_scene(seed, triangles, 0, 0, 0.08f);
  const Vec3 quad[4] = {{-floor, -floor, -1.5f}, {floor, -floor, -1.5f}, {floor, floor, -1.5f}, {-floor, floor, -1.5f}};
  s.add_polygon(quad, 4);
  return s;
}

// Fires random rays (origins in the grown box, half aimed at a primitive)
// and rays from inside the mesh through RayChecker.
void check_random_rays(const Built& b, std::uint64_t seed, int rays, const Bounds3& origins) {
  RayChecker rc(b);
  Rng rng(seed);
  for (int i = 0; i < rays; ++i) {
    const Vec3 o = random_in(rng, origins);
    Vec3 d = random_unit(rng);
    if (i % 2 == 0 && !b.db.primitives.empty()) {
      const Primitive& p = b.db.primitives[std::uniform_int_distribution<std::size_t>(0, b.db.primitives.size() - 1)(rng)];
      const Vec3 to = centre_of(p) - o;
      if (length(to) > 0) d = normalize(to);
    }
    rc.check(Ray{o, d, 0.0f, kInfinity});
  }
  rc.require_clean();
}

// The primitives leaf `leaf` lists.
std::vector<std::uint32_t> leaf_list(const Grid& grid, std::uint32_t leaf) {
  const auto list = grid.cell_primitives.begin();
  return {list + grid.cell_start[leaf], list + grid.cell_start[leaf + 1]};
}

// Every primitive listed in a cell of sub-grid `index` or below it (the
// large primitives beside its own cells, SubGrid::large_list, excepted).
std::vector<std::uint32_t> primitives_below(const Grid& grid, std::uint32_t index) {
  std::vector<std::uint32_t> ids;
  const SubGrid& g = grid.sub_grids[index];
  for (std::uint32_t c = 0; c < g.info.cell_count(); ++c) {
    const std::uint32_t e = grid.cell_entries[g.first_entry + c];
    std::vector<std::uint32_t> more;
    if (e & kSubGridEntry) {
      const SubGrid& child = grid.sub_grids[e & ~kSubGridEntry];
      more = primitives_below(grid, e & ~kSubGridEntry);
      if (child.large_list) {
        const std::vector<std::uint32_t> large = leaf_list(grid, child.first_entry + child.info.cell_count());
        more.insert(more.end(), large.begin(), large.end());
      }
    } else {
      more = leaf_list(grid, e);
    }
    ids.insert(ids.end(), more.begin(), more.end());
  }
  return ids;
}

ValidateReport validate(const Database& db, const Grid& grid) {
  const EmbreeScene embree(db);
  ValidateParams vp;
  vp.width = 48;
  vp.height = 48;
  vp.random_rays = 15000;
  return validate_grid(db, grid, embree, vp);
}

}  // namespace

TEST_CASE("adaptive grid: SPD scenes agree with Embree (zero mismatches) and hold sub-grids") {
  const struct {
    const char* spec;
    int tessellate;
  } cases[] = {{"teapot:3", 0}, {"mount:2", 0}, {"mount:1", 1}, {"rings:2", 0}, {"tetra:4", 0}, {"balls:2", 0}};
  for (const auto& c : cases)
    for (const bool deep : {false, true}) {
    CAPTURE(c.spec);
    CAPTURE(deep);
    const Database db = make_database(load_scene({c.spec, c.tessellate}));
    const Grid grid = build_grid(db, deep ? adaptive_deep() : adaptive());
    CHECK(grid.kind() == GridKind::kAdaptive);
    if (deep) CHECK(grid.sub_grid_count() > 0);
    const ValidateReport rep = validate(db, grid);
    INFO("mismatching rays:" << mismatch_lines(rep));
    CHECK(rep.total.mismatches() == 0);
    CHECK(rep.primary.grid_hits > 0);
    }
}

TEST_CASE("adaptive grid: a small mesh on a floor 300x its size agrees with brute force and Embree") {
  // (Embree's float test on a triangle 600 units wide errs by ~1e-5 units
  // in t: the origins stay 0.5 above the floor, so t stays within 1e-4.)
  const Built b(mesh_on_floor(11, 600, 300.0f), adaptive());
  // The floor (the last primitives) lies beside the top grid, which covers
  // the mesh's box alone, divided on all three axes.
  const std::uint32_t large = SubGridTables{b.grid.sub_grids, b.grid.cell_entries}.top_large_leaf();
  REQUIRE(large != kNoLeaf);
  const auto n = std::uint32_t(b.db.primitives.size());
  CHECK(leaf_list(b.grid, large) == std::vector<std::uint32_t>{n - 2, n - 1});  // the floor quad's two triangles
  for (int a = 0; a < 3; ++a) {
    CHECK(b.grid.info.bounds.lower[a] > -3.0f);
    CHECK(b.grid.info.bounds.upper[a] < 3.0f);
    CHECK(b.grid.info.res[a] > 1);
  }
  check_random_rays(b, 5, 3000, Bounds3{{-3, -3, -1.0f}, {3, 3, 3}});
  check_random_rays(b, 6, 1000, Bounds3{{-250, -250, 5.0f}, {250, 250, 50}});
  // Without that, the floor's top cell holds a sub-grid over the mesh, on all three axes.
  GridParams in_top = adaptive();
  in_top.large_beside_top = false;
  const Built c(mesh_on_floor(11, 600, 300.0f), in_top);
  CHECK(SubGridTables{c.grid.sub_grids, c.grid.cell_entries}.top_large_leaf() == kNoLeaf);
  CHECK(c.grid.depth() >= 1);
  bool deep_in_z = false;
  for (const SubGrid& s : c.grid.sub_grids) deep_in_z |= s.level > 0 && s.info.res[2] > 1;
  CHECK(deep_in_z);
  check_random_rays(c, 5, 3000, Bounds3{{-3, -3, -1.0f}, {3, 3, 3}});
  check_random_rays(c, 6, 1000, Bounds3{{-250, -250, 5.0f}, {250, 250, 50}});
}

TEST_CASE("adaptive grid: nested scales (a mesh on its own ground on a stadium floor) keep both floors beside the top grid") {
  Scene s = mesh_on_floor(12, 600, 4.0f);  // the mesh on a ground 8 units wide
  const Vec3 stadium[4] = {{-1200, -1200, -2}, {1200, -1200, -2}, {1200, 1200, -2}, {-1200, 1200, -2}};
  s.add_polygon(stadium, 4);
  const Built b(s, adaptive());
  // The stadium is large in the scene's box, the ground in what is left:
  // both beside the top grid, which covers the mesh's box alone.
  const std::uint32_t large = SubGridTables{b.grid.sub_grids, b.grid.cell_entries}.top_large_leaf();
  REQUIRE(large != kNoLeaf);
  const auto n = std::uint32_t(b.db.primitives.size());
  CHECK(leaf_list(b.grid, large) == std::vector<std::uint32_t>{n - 4, n - 3, n - 2, n - 1});
  for (int a = 0; a < 3; ++a) {
    CHECK(b.grid.info.bounds.lower[a] > -3.0f);
    CHECK(b.grid.info.bounds.upper[a] < 3.0f);
  }
  check_random_rays(b, 7, 3000, Bounds3{{-3, -3, -1.0f}, {3, 3, 3}});
  check_random_rays(b, 8, 1000, Bounds3{{-900, -900, 5.0f}, {900, 900, 50}});
}

TEST_CASE("adaptive grid: the primitives beside the top grid are tested only by rays that may meet their slab") {
  // One floor (z = -1.5), then two at different heights (-1.5 and -2).
  const Built one(mesh_on_floor(11, 600, 300.0f), adaptive());
  Scene nested = mesh_on_floor(12, 600, 4.0f);
  const Vec3 stadium[4] = {{-1200, -1200, -2}, {1200, -1200, -2}, {1200, 1200, -2}, {-1200, 1200, -2}};
  nested.add_polygon(stadium, 4);
  const Built two(nested, adaptive());
  for (const Built* b : {&one, &two}) {
    const PrimitiveSlab& slab = b->grid.info.large_slab;
    // Across the floor's normal, from its lowest to its highest point, widened by rounding only.
    CHECK(std::fabs(slab.normal[2]) == 1.0);
    const double low_z = b == &one ? -1.5 : -2.0, high_z = -1.5;
    const double lo = slab.normal[2] > 0 ? low_z : -high_z, hi = slab.normal[2] > 0 ? high_z : -low_z;
    CHECK(slab.lo <= lo);
    CHECK(slab.lo > lo - 1e-6);
    CHECK(slab.hi >= hi);
    CHECK(slab.hi < hi + 1e-6);
    const auto meets = [&](Vec3 o, Vec3 d) { return slab.may_meet(Ray{o, d, 0.0f, kInfinity}); };
    CHECK_FALSE(meets({0, 0, 0}, {0, 0, 1}));         // above, rising
    CHECK_FALSE(meets({5, 1, 0}, {1, 0, 0}));         // above, level
    CHECK(meets({0, 0, 0}, {0.3f, 0, -1}));           // above, falling
    CHECK_FALSE(meets({0, 0, -3}, {0, 0.5f, -1}));    // below, falling
    CHECK(meets({0, 0, -3}, {0, 0, 1}));              // below, rising
    CHECK(meets({0, 0, -1.5f}, {0, 0, 1}));           // on the floor: always tested
    // A ray spawned one float spacing above the floor, rising, cannot meet it.
    CHECK_FALSE(meets({0, 0, std::nextafter(-1.5f, 0.0f)}, {0, 0, 1}));
    CHECK(meets({0, 0, std::nextafter(-1.5f, 0.0f)}, {0, 0, -1}));
    // A piece of a ray in the tracing frame (tmin < 0) starts behind its
    // origin: just past the floor, it still meets it.
    const float below = float(low_z) - 1e-4f;
    CHECK_FALSE(slab.may_meet(Ray{{0, 0, below}, {0, 0, -1}, 0.0f, kInfinity}));
    CHECK(slab.may_meet(Ray{{0, 0, below}, {0, 0, -1}, -0.001f, kInfinity}));
  }
  // A ray rising from above the floor tests nothing: the floor is skipped.
  const DirectView view = one.view();
  for (const Vec3 o : {Vec3{0, 0, 10}, Vec3{100, 50, 0.5f}}) {
    TraversalScratch scratch;
    Hit hit;
    CHECK_FALSE(intersect_closest(view, Ray{o, normalize(Vec3{0.1f, 0.2f, 1}), 0.0f, kInfinity}, hit, scratch));
    CHECK(scratch.stats.triangle_tests == 0);
    // Falling, it tests the floor's two triangles and hits the floor.
    TraversalScratch down;
    REQUIRE(intersect_closest(view, Ray{o, normalize(Vec3{0.1f, 0.2f, -1}), 0.0f, kInfinity}, hit, down));
    CHECK(down.stats.triangle_tests >= 2);
  }
  // Rays from both sides of the floor and in every direction: brute force's
  // and Embree's hits (origins 0.5 from the floor, as Embree's float t on a
  // triangle 600 units wide errs by ~1e-5 units).
  check_random_rays(one, 9, 2000, Bounds3{{-3, -3, -3.0f}, {3, 3, -2.0f}});
  check_random_rays(one, 10, 2000, Bounds3{{-3, -3, -1.0f}, {3, 3, 3}});
}

TEST_CASE("adaptive grid: a ray from beyond the tracing frame hits a floor that it crosses at the frame's edge") {
  // The ray is tested in two pieces, before the frame and from its entry
  // point (framed_ray). A floor crossed within rounding of that point is
  // refused by the framed piece as the surface its origin lies on, so the
  // piece before the frame must reach past the entry by as much as its own
  // float t may err there.
  const Built b(mesh_on_floor(13, 600, 300.0f), adaptive());
  const DirectView view = b.view();
  const float frame = b.grid.info.frame_magnitude;
  const auto n = std::uint32_t(b.db.primitives.size());
  Rng rng(31);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  int split = 0;
  for (int i = 0; i < 4000; ++i) {
    const Vec3 o{frame + 20 + 40 * u01(rng), -10 + 20 * u01(rng), 3 + 10 * u01(rng)};
    const Vec3 target{frame * (1 + 4e-6f * (2 * u01(rng) - 1)), frame * (u01(rng) - 0.5f), -1.5f};
    const Ray ray{o, normalize(target - o), 0.0f, kInfinity};
    Ray framed;
    split += framed_ray(frame, ray, framed) > 0.0;
    TraversalScratch scratch;
    Hit hit;
    INFO(std::setprecision(9) << "ray " << i << ": o=(" << o.x << ", " << o.y << ", " << o.z << ") target=(" << target.x << ", " << target.y
                << ", " << target.z << ") frame " << frame);
    REQUIRE(intersect_closest(view, ray, hit, scratch));
    CHECK(hit.primitive >= n - 2);  // the floor, not the mesh behind it
    CHECK(std::fabs(hit.t - length(target - o)) < 1e-4f * hit.t);
  }
  CHECK(split == 4000);
}

TEST_CASE("adaptive grid: a stadium floor leaves the object's cells as they are, and rays from the far floor or a distant eye agree with brute force") {
  // The mesh on its own ground, alone and on a stadium floor 2e5 wide.
  const Scene alone = mesh_on_floor(21, 600, 4.0f);
  Scene stadium = alone;
  const Vec3 quad[4] = {{-1e5f, -1e5f, -2}, {1e5f, -1e5f, -2}, {1e5f, 1e5f, -2}, {-1e5f, 1e5f, -2}};
  stadium.add_polygon(quad, 4);
  const Built a(alone, adaptive()), b(stadium, adaptive());
  // The same top grid and the same cells: their margin is set by the top
  // grid's own magnitude, not by the floor's. The large leaf lists the
  // stadium's two triangles more.
  for (int k = 0; k < 3; ++k) {
    CHECK(b.grid.info.bounds.lower[k] == a.grid.info.bounds.lower[k]);
    CHECK(b.grid.info.bounds.upper[k] == a.grid.info.bounds.upper[k]);
    CHECK(b.grid.info.res[k] == a.grid.info.res[k]);
  }
  CHECK(b.grid.sub_grids.size() == a.grid.sub_grids.size());
  CHECK(b.grid.cell_primitives.size() == a.grid.cell_primitives.size() + 2);
  // Rays from the stadium floor, 1e3 to 9e4 away, just above it, to the
  // mesh, and from an eye 1e5 to 1e6 away (float spacing there is up to
  // 0.06, a triangle's size): they are tested from where they enter the
  // tracing frame. The grids agree with brute force in that frame bit for
  // bit, and with brute force from the far origin within its rounding.
  // (Embree tests from the far origin: at this distance its answers are
  // that rounding's, no oracle.)
  GridParams uniform_grid;
  uniform_grid.kind = GridKind::kUniform;
  const Built u(alone, uniform_grid);
  CHECK(u.grid.info.frame_magnitude == a.grid.info.frame_magnitude);  // the objects' box, whatever the grid
  Rng rng(22);
  for (const Built* built : {&b, &a, &u}) {
    const bool floor = built == &b;
    Failures bad;
    int hits = 0, far_hits = 0;
    TraversalScratch scratch;
    for (int i = 0; i < 3000; ++i) {
      Vec3 o;
      if (floor) {
        const float r = uniform(rng, 1e3f, 9e4f), phi = uniform(rng, 0.0f, 6.2831853f);
        o = Vec3{r * std::cos(phi), r * std::sin(phi), -1.9f};
      } else {
        const Vec3 e = random_unit(rng) * uniform(rng, 1e5f, 1e6f);
        o = Vec3{e.x, e.y, std::fabs(e.z) + 1e4f};
      }
      const Primitive& p = built->db.primitives[std::uniform_int_distribution<std::uint32_t>(0, 599)(rng)];
      const Ray ray{o, normalize(centre_of(p) - o), 0.0f, kInfinity};
      Hit g;
      const bool found = intersect_closest(built->view(), ray, g, scratch);
      const Hit r = brute_closest(*built, ray);
      hits += found;
      if (found != r.found() || (found && (g.t != r.t || g.primitive != r.primitive)))
        bad.add(str(ray) + ": grid " + str(g) + ", brute force " + str(r));
      if (intersect_any(built->view(), ray, scratch) != found) bad.add(str(ray) + ": any-hit disagrees");
      // From the far origin: the same t within the rounding of its distance.
      const Hit f = brute_closest(built->db, ray, 0.0f);
      if (found && f.found() && std::fabs(f.t - g.t) <= 1e-5f * g.t) ++far_hits;
    }
    CAPTURE(floor);
    INFO("mismatches:" << bad.first);
    CHECK(bad.count == 0);
    CHECK(hits > 2500);
    CHECK(far_hits > 2400);
  }
}

TEST_CASE("adaptive grid: a floor under a mesh stays beside the mesh's grid (top or sub-grid), whose box is the mesh's") {
  for (const bool beside_top : {true, false}) {
  CAPTURE(beside_top);
  GridParams params = adaptive();
  params.large_beside_top = beside_top;
  const Built b(mesh_on_floor(13, 600, 300.0f), params);
  // The floor's two triangles: the primitives wider than 100.
  std::vector<std::uint32_t> floor;
  for (std::uint32_t id = 0; id < b.db.primitives.size(); ++id)
    if (b.db.primitives[id].bounds().extent().x > 100) floor.push_back(id);
  REQUIRE(floor.size() == 2);
  int beside = 0;
  for (const SubGrid& g : b.grid.sub_grids) {
    if (!g.large_list) continue;
    ++beside;
    CHECK((g.level == 0) == beside_top);
    CHECK(leaf_list(b.grid, g.first_entry + g.info.cell_count()) == floor);
    // Above the floor (z = -1.5) and about as wide as the mesh (~2).
    CHECK(g.info.bounds.lower.z > -1.5f);
    CHECK(g.info.bounds.extent().x < 3.0f);
    CHECK(g.info.bounds.extent().y < 3.0f);
  }
  CHECK(beside == 1);
  // Rays from around the mesh (many hit the floor near it, under the
  // sub-grid's box), from far above, from below the floor, and segments
  // ending before, on and beyond the mesh (shadow rays).
  // (Origins 0.5 above the floor, as above: Embree's float test on the
  // 600-unit floor errs by ~1e-5 in t.)
  check_random_rays(b, 14, 3000, Bounds3{{-3, -3, -1.0f}, {3, 3, 3}});
  check_random_rays(b, 15, 1000, Bounds3{{-250, -250, 5.0f}, {250, 250, 50}});
  check_random_rays(b, 16, 500, Bounds3{{-3, -3, -5.0f}, {3, 3, -2.0f}});
  RayChecker rc(b);
  Rng rng(17);
  for (int i = 0; i < 3000; ++i) {
    const Vec3 o = random_in(rng, Bounds3{{-3, -3, -1.0f}, {3, 3, 3}});
    const Vec3 to = random_in(rng, Bounds3{{-2, -2, -1.6f}, {2, 2, 1}});
    if (length(to - o) > 0) rc.check(Ray{o, to - o, 0.0f, uniform(rng, 0.1f, 1.5f)});
  }
  rc.require_clean();
  }
}

// Records the exit parameter of every leaf a walk visits, in order, and
// steers the walk as the tracer's visit does (the cell's code: its empty
// distance, or kSubGridCode + i to descend), never stopping it.
struct LeafRecorder {
  const DirectView* view;
  std::vector<float>* t_exits;
  std::uint32_t operator()(std::uint32_t cell, float t_exit) {
    const std::uint32_t code = view->for_each_in_cell(cell, [](std::uint32_t) {});
    if (code < kSubGridCode) t_exits->push_back(t_exit);
    return code;
  }
};

TEST_CASE("adaptive grid: a closest hit ends the walk at the first leaf it lies within, a floor's beside a sub-grid too") {
  Scene scene = load_scene({"tetra:6", 0});
  const Vec3 quad[4] = {{-1000, -1000, -1.01f}, {1000, -1000, -1.01f}, {1000, 1000, -1.01f}, {-1000, 1000, -1.01f}};
  scene.add_polygon(quad, 4);
  const Built b(scene, adaptive());
  const DirectView view = b.view();
  // Rays from the eye and from around the tetrahedra, to the floor under
  // them and to the tetrahedra: many cross their sub-grid, whose cells do
  // not list the floor, and hit the floor, found in the large-primitive
  // leaf visited first.
  Rng rng(23);
  int floor_hits = 0, ended_early = 0;
  // The eye, moved along its line into the tracing frame if need be.
  const Vec3 eye = scene.view.from *
                   std::min(1.0f, 0.95f * b.grid.info.frame_magnitude / max_component(abs(scene.view.from)));
  for (int i = 0; i < 4000; ++i) {
    const Vec3 o = i % 2 ? eye : random_in(rng, Bounds3{{-2, -2, -0.9f}, {2, 2, 2}});
    // (Within the tracing frame, so that the ray is walked whole, as here.)
    REQUIRE(max_component(abs(o)) <= b.grid.info.frame_magnitude);
    const Vec3 to = random_in(rng, Bounds3{{-1.5f, -1.5f, -1.01f}, {1.5f, 1.5f, i % 4 < 2 ? -1.01f : 1.0f}});
    const Ray ray{o, normalize(to - o), 0.0f, kInfinity};
    TraversalScratch scratch;
    Hit hit;
    if (!intersect_closest(view, ray, hit, scratch)) continue;
    floor_hits += b.db.primitives[hit.primitive].bounds().extent().x > 100;
    std::vector<float> t_exits;
    LeafRecorder record{&view, &t_exits};
    walk_cells(view, ray, record);
    // The walk visits every leaf up to the first whose exit lies at or
    // beyond the hit (a large-primitive leaf, t_exit -inf, ends nothing),
    // or to its end.
    std::size_t expect = 0;
    while (expect < t_exits.size() && !(t_exits[expect] >= hit.t)) ++expect;
    ended_early += expect + 1 < t_exits.size();
    CHECK(scratch.stats.cells_visited == std::min(expect + 1, t_exits.size()));
  }
  CHECK(floor_hits > 200);
  CHECK(ended_early > 100);
}

TEST_CASE("adaptive grid: random triangle soups with spheres and cones agree with brute force and Embree") {
  for (std::uint64_t seed : {1, 2, 3}) {
    CAPTURE(seed);
    const Built b(random_scene(seed, 500, 30, 20, 0.15f), adaptive());
    CHECK(b.grid.kind() == GridKind::kAdaptive);
    check_random_rays(b, seed + 100, 1500, grown(b.db.bounds, 0.5f));
  }
  // Clustered: a dense clump inside a sparse soup forces sub-grids.
  Scene s = random_scene(9, 300, 0, 0, 0.3f);
  const Scene clump = random_scene(10, 800, 0, 0, 0.01f);
  for (const Primitive& p : make_database(clump).primitives) {
    const Vec3 v[3] = {p.vertex(0) * 0.05f, p.vertex(1) * 0.05f, p.vertex(2) * 0.05f};
    s.add_polygon(v, 3);
  }
  const Built b(s, adaptive_deep());
  CHECK(b.grid.sub_grid_count() > 0);
  check_random_rays(b, 42, 2000, Bounds3{{-0.2f, -0.2f, -0.2f}, {0.2f, 0.2f, 0.2f}});
  check_random_rays(b, 43, 1000, grown(b.db.bounds, 0.5f));
}

TEST_CASE("adaptive grid: packed cells inside sub-grids give the same hits as the lists") {
  GridParams in_top = adaptive();  // the floor in the top grid, so that its cell holds a sub-grid
  in_top.large_beside_top = false;
  const Built b(mesh_on_floor(12, 800, 300.0f), in_top);
  REQUIRE(b.grid.sub_grid_count() > 0);
  CHECK(b.blocks.blocks.size() > 0);
  TraversalScratch s1, s2;
  Rng rng(3);
  std::size_t hits = 0, differ = 0;
  for (int i = 0; i < 3000; ++i) {
    const Vec3 o = random_in(rng, Bounds3{{-4, -4, -1}, {4, 4, 4}});
    const Ray r{o, random_unit(rng), 0.0f, kInfinity};
    Hit a, p;
    const bool fa = intersect_closest(b.view(), r, a, s1);
    const bool fp = intersect_closest(b.packed_view(), r, p, s2);
    hits += fa;
    differ += fa != fp || a.t != p.t || a.primitive != p.primitive;
  }
  CHECK(hits > 100);
  CHECK(differ == 0);
}

TEST_CASE("adaptive grid: images equal the uniform grid's (byte for byte)") {
  for (const char* spec : {"teapot:3", "balls:2", "tetra:3"})
    for (const bool deep : {false, true}) {
    CAPTURE(spec);
    CAPTURE(deep);
    const Database db = make_database(load_scene({spec, 0}));
    const Grid uniform = build_grid(db);
    const Grid adapt = build_grid(db, deep ? adaptive_deep() : adaptive());
    REQUIRE(adapt.kind() == GridKind::kAdaptive);
    if (deep) CHECK(adapt.sub_grid_count() > 0);
    RenderParams rp;
    rp.width = 64;
    rp.height = 64;
    const RenderResult a = render(db, uniform, rp);
    const RenderResult b = render(db, adapt, rp);
    REQUIRE(a.color.pixels.size() == b.color.pixels.size());
    std::size_t differ = 0;
    for (std::size_t i = 0; i < a.color.pixels.size(); ++i) differ += a.color.pixels[i] != b.color.pixels[i];
    CHECK(differ == 0);
    }
}

TEST_CASE("adaptive grid: an empty database builds one empty top cell and every ray misses") {
  const Built b(Scene{}, adaptive());
  CHECK(b.grid.kind() == GridKind::kAdaptive);
  CHECK(b.grid.info.cell_count() == 1);
  CHECK(b.grid.leaf_cells() == 1);
  CHECK(b.grid.references() == 0);
  TraversalScratch scratch;
  Hit h;
  CHECK_FALSE(intersect_closest(b.view(), Ray{{0, 0, -5}, {0, 0, 1}, 0.0f, kInfinity}, h, scratch));
  CHECK_FALSE(intersect_any(b.view(), Ray{{0, 0, -5}, {0, 0, 1}, 0.0f, kInfinity}, scratch));
}

TEST_CASE("adaptive grid: one primitive is hit like brute force, from outside and inside the grid") {
  Scene s;
  const Vec3 tri[3] = {{-1, -1, 0}, {1, -1, 0}, {0, 1, 0}};
  s.add_polygon(tri, 3);
  const Built b(s, adaptive());
  CHECK(b.grid.references() >= 1);
  RayChecker rc(b);
  const Hit h = rc.check(Ray{{0, -0.2f, 3}, {0, 0, -1}, 0.0f, kInfinity});
  CHECK(h.found());
  rc.check(Ray{{0, -0.2f, 0.00001f}, {0.1f, 0.05f, -1}, 0.0f, kInfinity});  // starts inside the grid box
  rc.check(Ray{{5, 5, 5}, {1, 0, 0}, 0.0f, kInfinity});                      // misses
  rc.require_clean();
}

TEST_CASE("adaptive grid: all primitives in one top cell are refined in a sub-grid") {
  GridParams p = adaptive();
  p.resolution[0] = p.resolution[1] = p.resolution[2] = 1;  // the top grid forced to one cell
  const Built b(random_scene(21, 600, 0, 0, 0.05f), p);
  CHECK(b.grid.info.cell_count() == 1);
  REQUIRE(b.grid.sub_grid_count() >= 1);
  CHECK(b.grid.cell_entries[0] == (kSubGridEntry | 1u));
  check_random_rays(b, 22, 1500, grown(b.db.bounds, 0.3f));
}

TEST_CASE("adaptive grid: a sub-grid covers only the part of its cell that its primitives reach") {
  // A mesh of size ~2 at the origin and one triangle 1000 away: the mesh
  // fills a corner of one top cell 500 wide.
  Scene s = random_scene(25, 600, 0, 0, 0.05f);
  const Vec3 far_away[3] = {{1000, 1000, 1000}, {1001, 1000, 1000}, {1000, 1001, 1000}};
  s.add_polygon(far_away, 3);
  GridParams p = adaptive();
  p.resolution[0] = p.resolution[1] = p.resolution[2] = 2;
  const Built b(s, p);
  REQUIRE(b.grid.sub_grid_count() >= 1);
  REQUIRE((b.grid.cell_entries[0] & kSubGridEntry) != 0);
  const SubGrid& child = b.grid.sub_grids[b.grid.cell_entries[0] & ~kSubGridEntry];
  Bounds3 mesh;
  for (const Primitive& q : b.db.primitives)
    if (q.bounds().upper.x < 500) mesh.extend(q.bounds());
  for (int a = 0; a < 3; ++a) {
    CHECK(child.info.bounds.lower[a] <= mesh.lower[a]);
    CHECK(child.info.bounds.upper[a] >= mesh.upper[a]);
    CHECK(child.info.bounds.extent()[a] < 1.1f * mesh.extent()[a]);  // the cell is 250x wider
  }
  // Rays from inside the sub-grid's box, from the rest of its cell, and
  // from beyond the grid.
  check_random_rays(b, 26, 1500, grown(mesh, 0.1f));
  check_random_rays(b, 27, 1500, Bounds3{{-1, -1, -1}, {400, 400, 400}});
  check_random_rays(b, 28, 500, Bounds3{{-2000, -2000, -2000}, {2000, 2000, 2000}});
}

TEST_CASE("adaptive grid: a flat scene and an extremely elongated scene agree with brute force and Embree") {
  Rng rng(31);
  Scene flat, thin;
  for (int i = 0; i < 400; ++i) {
    const float x = uniform(rng, -10, 10), y = uniform(rng, -10, 10);
    const Vec3 f[3] = {{x, y, 0}, {x + 0.3f, y, 0}, {x, y + 0.3f, 0}};
    flat.add_polygon(f, 3);
    const float u = uniform(rng, -5000, 5000);
    const Vec3 t[3] = {{u, -0.5f, -0.5f}, {u + 2, 0.5f, -0.5f}, {u + 1, 0, 0.5f}};
    thin.add_polygon(t, 3);
  }
  const Built bf(flat, adaptive());
  const Built bt(thin, adaptive());
  // The long axis gets many top cells; the flat one's plane is divided.
  CHECK(bt.grid.info.res[0] > 16);
  CHECK(bf.grid.info.res[0] > 1);
  CHECK(bf.grid.info.res[1] > 1);
  check_random_rays(bf, 32, 1500, Bounds3{{-12, -12, -3}, {12, 12, 3}});
  check_random_rays(bt, 33, 1500, Bounds3{{-6000, -3, -3}, {6000, 3, 3}});
}

TEST_CASE("adaptive grid: rays on a top-cell boundary and axis-parallel rays agree with brute force") {
  const Built b(mesh_on_floor(41, 800, 50.0f), adaptive());
  REQUIRE(b.grid.info.res[0] > 1);
  RayChecker rc(b);
  const GridInfo& top = b.grid.info;
  Rng rng(42);
  for (int i = 1; i < top.res[0]; ++i) {
    // Origins exactly on a top-cell boundary plane x = lower + i * size.
    const float x = top.bounds.lower.x + float(i) * top.cell_size.x;
    for (int k = 0; k < 20; ++k) {
      const Vec3 o{x, uniform(rng, -2, 2), uniform(rng, -1.4f, 2)};
      rc.check(Ray{o, random_unit(rng), 0.0f, kInfinity});
      rc.check(Ray{o, {0, 0, -1}, 0.0f, kInfinity});
      rc.check(Ray{o, {1, 0, 0}, 0.0f, kInfinity});
      rc.check(Ray{o, {-1, 0, 0}, 0.0f, kInfinity});
    }
  }
  for (int k = 0; k < 300; ++k) {
    // Axis-parallel rays through the mesh, from outside the grid and from inside.
    const float a = uniform(rng, -1.2f, 1.2f), c = uniform(rng, -1.2f, 1.2f);
    rc.check(Ray{{a, c, 100}, {0, 0, -1}, 0.0f, kInfinity});
    rc.check(Ray{{-100, a, c}, {1, 0, 0}, 0.0f, kInfinity});
    rc.check(Ray{{a, 100, c}, {0, -1, 0}, 0.0f, kInfinity});
    rc.check(Ray{{a, c, 0.0f}, {0, 1, 0}, 0.0f, kInfinity});
  }
  CHECK(rc.hits > 500);
  rc.require_clean();
}

TEST_CASE("adaptive grid: --grid uniform's grid is today's uniform grid, unchanged") {
  const Database db = make_database(load_scene({"teapot:3", 0}));
  GridParams p;
  p.kind = GridKind::kUniform;
  const Grid u = build_grid(db, p);
  const Grid d = build_grid(db);  // GridParams' default kind
  CHECK(u.kind() == GridKind::kUniform);
  CHECK(u.sub_grids.empty());
  CHECK(u.cell_entries.empty());
  CHECK(u.leaf_cells() == u.info.cell_count());
  CHECK(u.cell_start == d.cell_start);
  CHECK(u.cell_primitives == d.cell_primitives);
  CHECK(u.empty_distance == d.empty_distance);
}

TEST_CASE("adaptive grid: every leaf cell is reached exactly once from the top grid") {
  const Built b(mesh_on_floor(51, 1000, 200.0f), adaptive_deep());
  CHECK(b.grid.depth() == 2);
  std::vector<int> seen(b.grid.leaf_cells(), 0);
  // The floor's leaf beside the top grid, after the top grid's cells.
  REQUIRE(b.grid.sub_grids[0].large_list);
  ++seen.at(b.grid.info.cell_count());
  for (const SubGrid& s : b.grid.sub_grids)
    for (std::uint32_t c = 0; c < s.info.cell_count(); ++c) {
      const std::uint32_t e = b.grid.cell_entries[s.first_entry + c];
      // A cell holds a sub-grid exactly when its leaf's distance byte is the
      // mark (the top walk reads no entry but for those).
      CHECK((b.grid.empty_distance[s.first_entry + c] == kSubGridMark) == bool(e & kSubGridEntry));
      // Every cell is leaf first_entry + c; a cell holding a sub-grid keeps
      // an empty placeholder there.
      REQUIRE(s.first_entry + c < seen.size());
      ++seen[s.first_entry + c];
      if (!(e & kSubGridEntry)) {
        CHECK(e == s.first_entry + c);
      } else {
        CHECK(b.grid.cell_start[s.first_entry + c] == b.grid.cell_start[s.first_entry + c + 1]);
        // A sub-grid lies within its parent cell's box and holds the part
        // of that box every primitive below it reaches.
        const std::uint32_t ci = e & ~kSubGridEntry;
        const SubGrid& child = b.grid.sub_grids[ci];
        const int x = int(c % std::uint32_t(s.info.res[0]));
        const int y = int(c / std::uint32_t(s.info.res[0]) % std::uint32_t(s.info.res[1]));
        const int z = int(c / (std::uint32_t(s.info.res[0]) * std::uint32_t(s.info.res[1])));
        const Bounds3 cb = s.info.cell_bounds(x, y, z);
        CHECK(child.level == s.level + 1);
        if (child.large_list) {  // its leaf after its cells
          REQUIRE(child.first_entry + child.info.cell_count() < seen.size());
          ++seen[child.first_entry + child.info.cell_count()];
          CHECK(b.grid.cell_entries[child.first_entry + child.info.cell_count()] ==
                child.first_entry + child.info.cell_count());
        }
        for (int a = 0; a < 3; ++a) {
          CHECK(child.info.bounds.lower[a] >= cb.lower[a]);
          CHECK(child.info.bounds.upper[a] <= cb.upper[a]);
        }
        for (const std::uint32_t id : primitives_below(b.grid, ci)) {
          const Bounds3 pb = b.db.primitives[id].bounds();
          for (int a = 0; a < 3; ++a) {
            CHECK(child.info.bounds.lower[a] <= std::max(pb.lower[a], cb.lower[a]));
            CHECK(child.info.bounds.upper[a] >= std::min(pb.upper[a], cb.upper[a]));
          }
        }
      }
    }
  std::size_t bad = 0;
  for (int n : seen) bad += n != 1;
  CHECK(bad == 0);
}

TEST_CASE("adaptive grid: a build that refines no cell keeps only its top grid, the uniform grid's layout") {
  // Tetra's cells list a few triangles each: nothing reaches sub_grid_min.
  const Database db = make_database(load_scene({"tetra:4", 0}));
  const Grid a = build_grid(db, adaptive());
  const Grid u = build_grid(db);
  CHECK(a.kind() == GridKind::kAdaptive);
  CHECK(a.sub_grid_count() == 0);
  CHECK(a.sub_grids.empty());
  CHECK(a.cell_entries.empty());
  CHECK(a.depth() == 0);
  CHECK(a.leaf_cells() == a.info.cell_count());
  // Same resolution rule on a cube-like scene: the same cells and lists.
  for (int k = 0; k < 3; ++k) CHECK(a.info.res[k] == u.info.res[k]);
  CHECK(a.cell_start == u.cell_start);
  CHECK(a.cell_primitives == u.cell_primitives);
  CHECK(a.empty_distance == u.empty_distance);
  // A deep build of the same scene does refine.
  CHECK(build_grid(db, adaptive_deep()).sub_grid_count() > 0);
}

TEST_CASE("adaptive grid: cells crowded by large overlapping spheres stay leaves, a crowded mesh cell is refined") {
  // SPD shells nests spheres around spheres: a ray crossing a sub-grid of
  // one of its crowded cells would meet most of the spheres the leaf lists
  // (each crosses most sub-cells), so the cost model's walk bound
  // (GridParams::sub_grid_walk_share) keeps the leaf. (Bounded by the leaf's count alone,
  // shells:4 got 4 sub-grids and 3.2x the references.)
  const Database db = make_database(load_scene({"shells:4", 0}));
  const Grid grid = build_grid(db, adaptive());
  CHECK(grid.sub_grid_count() == 0);
  // Some cell is crowded enough to be considered (its list is long).
  std::uint32_t longest = 0;
  for (std::uint32_t c = 0; c < grid.leaf_cells(); ++c)
    longest = std::max(longest, grid.cell_start[c + 1] - grid.cell_start[c]);
  CHECK(longest >= adaptive().sub_grid_min);
  // 600 small triangles in one cell: refined.
  GridParams p = adaptive();
  p.resolution[0] = p.resolution[1] = p.resolution[2] = 1;
  CHECK(build_grid(make_database(random_scene(21, 600, 0, 0, 0.05f)), p).sub_grid_count() >= 1);
}

TEST_CASE("adaptive grid: a cone counts cone_weight in the resolution rule, and sub_grid_min weighs the cell's primitives") {
  const auto cells = [](const Database& db, GridParams p) { return double(build_grid(db, p).info.cell_count()); };
  // About density x 4 x cones top cells, against density x cones at weight 1.
  const Database cones = make_database(random_scene(44, 0, 0, 3000, 0.01f));
  GridParams whole = adaptive();
  whole.cone_weight = 1.0f;
  CHECK(adaptive().cone_weight == kConeWeight);
  CHECK(cells(cones, adaptive()) / cells(cones, whole) == doctest::Approx(kConeWeight).epsilon(0.25));
  // One top cell over a few small primitives: offered a sub-grid only when
  // they weigh sub_grid_min (32) or more.
  const auto refined = [](const Scene& s, float triangle_weight, float cone_weight) {
    GridParams p = adaptive();
    p.resolution[0] = p.resolution[1] = p.resolution[2] = 1;
    p.triangle_weight = triangle_weight;
    p.cone_weight = cone_weight;
    return build_grid(make_database(s), p).sub_grid_count() > 0;
  };
  const Scene ten_cones = random_scene(45, 0, 0, 10, 0.02f);  // weighs 40, or 10 counted whole
  CHECK(refined(ten_cones, 1.0f, kConeWeight));
  CHECK_FALSE(refined(ten_cones, 1.0f, 1.0f));
  const Scene triangles = random_scene(46, 60, 0, 0, 0.02f);  // weighs 60 listed, 15 packed
  CHECK(refined(triangles, 1.0f, kConeWeight));
  CHECK_FALSE(refined(triangles, kPackedTriangleWeight, kConeWeight));
}

TEST_CASE("adaptive grid: a triangle counts triangle_weight of a primitive in the resolution rule, a sphere whole") {
  // Top cells, from the cube-root rule: about density x (spheres + cones +
  // weight x triangles), give or take each axis's rounding.
  const auto top_cells = [](const Scene& s, float weight) {
    GridParams p = adaptive();
    p.triangle_weight = weight;
    const Database db = make_database(s);
    return double(build_grid(db, p).info.cell_count());
  };
  const Scene triangles = random_scene(41, 4000, 0, 0, 0.01f);
  const Scene spheres = random_scene(42, 0, 2000, 0, 0.01f);
  const Scene mixed = random_scene(43, 2000, 2000, 0, 0.01f);
  const double tri_ratio = top_cells(triangles, kPackedTriangleWeight) / top_cells(triangles, 1.0f);
  CHECK(tri_ratio == doctest::Approx(kPackedTriangleWeight).epsilon(0.25));
  CHECK(top_cells(spheres, kPackedTriangleWeight) == top_cells(spheres, 1.0f));
  // 2000 + 500 of 4000 units.
  CHECK(top_cells(mixed, kPackedTriangleWeight) / top_cells(mixed, 1.0f) == doctest::Approx(0.625).epsilon(0.2));
  // The weight is the adaptive grid's: the paper's uniform grid keeps its resolution.
  GridParams uniform;
  uniform.triangle_weight = kPackedTriangleWeight;
  const Database db = make_database(triangles);
  CHECK(build_grid(db, uniform).info.cell_count() == build_grid(db, GridParams{}).info.cell_count());
  // grid_params_for_packed_cells sets it only for a tracer that packs.
  CHECK(grid_params_for_packed_cells(adaptive(), 0).triangle_weight == 1.0f);
  CHECK(grid_params_for_packed_cells(adaptive(), kDefaultPackMin).triangle_weight == kPackedTriangleWeight);
}

TEST_CASE("grid build: the same lists on one thread and on four (runs of primitives merged in order)") {
  // Each build runs in an arena of a fixed size, so the many-thread path is
  // taken on any machine (an arena may have more slots than cores).
  const struct {
    const char* spec;
    int tessellate;
    GridParams params;
  } cases[] = {{"tetra:6", 0, adaptive()},
               {"tetra:6", 0, GridParams{.kind = GridKind::kUniform}},
               {"balls:3", 1, adaptive()},
               {"shells:5", 0, adaptive()},
               {"teapot:8", 0, adaptive_deep()}};
  for (const auto& c : cases) {
    const std::string spec = c.spec, kind = grid_kind_name(c.params.kind);
    CAPTURE(spec);
    CAPTURE(kind);
    const Database db = make_database(load_scene({c.spec, c.tessellate}));
    REQUIRE(db.primitives.size() >= 4096);  // several runs of primitives on four threads
    Grid one, four;
    tbb::task_arena(1).execute([&] { one = build_grid(db, c.params); });
    tbb::task_arena(4).execute([&] { four = build_grid(db, c.params); });
    CHECK(one.cell_primitives.size() > db.primitives.size());
    CHECK(four.cell_start == one.cell_start);
    CHECK(four.cell_primitives == one.cell_primitives);
    CHECK(four.empty_distance == one.empty_distance);
    CHECK(four.cell_entries == one.cell_entries);
    REQUIRE(four.sub_grids.size() == one.sub_grids.size());
    for (std::size_t i = 0; i < one.sub_grids.size(); ++i) {
      CHECK(four.sub_grids[i].first_entry == one.sub_grids[i].first_entry);
      CHECK(four.sub_grids[i].info.cell_count() == one.sub_grids[i].info.cell_count());
    }
    if (spec == "teapot:8") CHECK(one.sub_grids.size() > 2);  // sub-grid choices made in parallel
  }
}
