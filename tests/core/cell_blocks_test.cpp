// Packed cells (core/cell_blocks.h): which cells are packed and what their
// blocks hold, and that tracing through them gives the same hits, bit for
// bit (t, u, v, primitive) and the same any-hit answers as walking the
// cells' primitive lists, which is what keeps sequential mode's images
// identical to the node modes'.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/cell_blocks.h"
#include "core/database.h"
#include "core/direct_view.h"
#include "core/grid.h"
#include "core/scene.h"
#include "core/scene_source.h"
#include "core/scene_transform.h"
#include "core/shade.h"
#include "core/spawn.h"
#include "core/traverse.h"
#include "grid_test_support.h"

namespace {
using namespace raynode::core;
using namespace raynode::testing::grid;

bool same_bits(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

/// Whether leaf cell `c` lists primitives, all spheres (a sphere cell that may be packed).
bool lists_only_spheres(const Database& db, const Grid& grid, std::uint32_t c) {
  bool all = grid.cell_start[c + 1] > grid.cell_start[c];
  for (std::uint32_t i = grid.cell_start[c]; i < grid.cell_start[c + 1]; ++i)
    all &= db.primitives[grid.cell_primitives[i]].kind == PrimitiveKind::kSphere;
  return all;
}

/// Fires `rays` through both views and counts the rays whose closest hit
/// (t, u, v, primitive, bit for bit) or any-hit answer differ.
struct Comparison {
  std::size_t rays = 0, hits = 0, differ = 0;
  std::string first;
  void fire(const DirectView& list, const DirectView& packed, const Ray& ray, TraversalScratch& scratch) {
    if (!is_valid_ray(ray)) return;
    ++rays;
    Hit a, b;
    const bool fa = intersect_closest(list, ray, a, scratch);
    const bool fb = intersect_closest(packed, ray, b, scratch);
    const bool aa = intersect_any(list, ray, scratch);
    const bool ab = intersect_any(packed, ray, scratch);
    hits += fa;
    const bool same = fa == fb && aa == ab && a.primitive == b.primitive && same_bits(a.t, b.t) &&
                      same_bits(a.u, b.u) && same_bits(a.v, b.v);
    if (!same && differ++ == 0) first = str(ray) + ": lists " + str(a) + ", packed " + str(b);
  }
};

}  // namespace

TEST_CASE("cell blocks: a packed cell holds its list's triangles in order, lane by lane, other cells hold none") {
  const Scene scene = load_scene({"tetra:4", 0});
  const Database db = make_database(scene);
  const Grid grid = build_grid(db);
  for (std::uint32_t min : {1u, 3u, 9u}) {
    CAPTURE(min);
    const CellBlocks cb = build_cell_blocks(db, grid, min);
    REQUIRE(cb.start.size() == std::size_t(grid.info.cell_count()) + 1);
    REQUIRE(cb.start.back() == cb.blocks.size());
    std::size_t packed = 0, lanes = 0;
    for (std::uint32_t c = 0; c < grid.info.cell_count(); ++c) {
      const std::uint32_t n = grid.cell_start[c + 1] - grid.cell_start[c];
      const std::uint32_t blocks = cb.start[c + 1] - cb.start[c];
      if (n < min) {
        CHECK(blocks == 0);
        continue;
      }
      ++packed;
      REQUIRE(blocks == (n + kBlockLanes - 1) / kBlockLanes);
      for (std::uint32_t i = 0; i < n; ++i, ++lanes) {
        const TriangleBlock& b = cb.blocks[cb.start[c] + i / kBlockLanes];
        const std::uint32_t l = i % kBlockLanes, id = grid.cell_primitives[grid.cell_start[c] + i];
        REQUIRE(b.primitive[l] == id);
        for (int v = 0; v < 3; ++v)
          for (int a = 0; a < 3; ++a) REQUIRE(same_bits(b.v[v][a][l], db.primitives[id].data[3 * v + a]));
      }
    }
    CHECK(packed > 0);
    CHECK(lanes <= cb.blocks.size() * kBlockLanes);
  }
  CHECK_THROWS_AS(build_cell_blocks(db, grid, 0), std::invalid_argument);
}

TEST_CASE("cell blocks: a cell that lists a sphere or a cone is not packed, and its neighbours still are") {
  Scene s;
  // A fan of 12 triangles around the origin, a sphere inside the fan's cell.
  for (int i = 0; i < 12; ++i) {
    const float a0 = 0.5236f * float(i), a1 = 0.5236f * float(i + 1);
    const Vec3 tri[3] = {Vec3{0, 0, 0.01f * float(i)}, Vec3{std::cos(a0), std::sin(a0), 0},
                         Vec3{std::cos(a1), std::sin(a1), 0}};
    s.add_polygon(tri, 3);
  }
  s.add_sphere({Vec3{0.1f, 0.1f, 0.05f}, 0.05f});
  const Built b(s, forced(1, 1, 1));
  REQUIRE(b.grid.cell_start[1] == 13);
  CHECK(b.blocks.blocks.empty());  // the only cell lists the sphere
  const Built b2(s, forced(4, 4, 1));
  CHECK(!b2.blocks.blocks.empty());  // cells away from the sphere hold only triangles
  for (std::uint32_t c = 0; c < b2.grid.info.cell_count(); ++c) {
    bool sphere = false;
    for (std::uint32_t i = b2.grid.cell_start[c]; i < b2.grid.cell_start[c + 1]; ++i)
      sphere |= b2.db.primitives[b2.grid.cell_primitives[i]].kind != PrimitiveKind::kTriangle;
    if (sphere) CHECK(b2.blocks.start[c] == b2.blocks.start[c + 1]);
  }
}

TEST_CASE("cell blocks: packed and listed cells give bit-identical hits and any-hit answers on SPD scenes") {
  struct Case {
    const char* spec;
    int tessellate;
  };
  for (const Case& c : {Case{"tetra:6", 0}, Case{"teapot:6", 0}, Case{"mount:4", 0}, Case{"balls:2", 2},
                        Case{"rings:2", 1}}) {
    CAPTURE(c.spec);
    const Scene scene = load_scene({c.spec, c.tessellate});
    const Database db = make_database(scene);
    for (const float density : {0.5f, 2.0f, 8.0f}) {
      CAPTURE(density);
      GridParams gp;
      gp.density = density;
      const Grid grid = build_grid(db, gp);
      const DirectView list(db, grid);
      for (std::uint32_t min : {1u, kDefaultPackMin, 8u}) {
        CAPTURE(min);
        const CellBlocks cb = build_cell_blocks(db, grid, min);
        const DirectView packed(db, grid, &cb);
        TraversalScratch scratch;
        Comparison cmp;
        Rng rng(7 + min);
        const Bounds3 box = grown(db.bounds, 0.3f);
        for (int i = 0; i < 3000; ++i) {
          const Vec3 o = random_in(rng, box);
          // Half toward a primitive's vertex or edge midpoint (shared
          // vertices and edges: the double fallback), half at random.
          Vec3 d = random_unit(rng);
          if (i % 2) {
            const Primitive& p = db.primitives[rng() % db.primitives.size()];
            if (p.kind == PrimitiveKind::kTriangle) {
              const int k = int(rng() % 3);
              const Vec3 t = (i % 4 == 1) ? p.vertex(k) : (p.vertex(k) + p.vertex((k + 1) % 3)) * 0.5f;
              d = t - o;
            }
          }
          cmp.fire(list, packed, Ray{o, d, 0.0f, kInfinity}, scratch);
          // Shadow-like segments that end short of the scene.
          cmp.fire(list, packed, Ray{o, d, 0.0f, uniform(rng, 0.0f, 1.0f) * length(box.extent())}, scratch);
        }
        // Axis-parallel rays along cell planes.
        for (int i = 0; i < 300; ++i) {
          Vec3 o = random_in(rng, box), d{0, 0, 0};
          const int a = i % 3;
          o[a] = box.lower[a];
          d[a] = 1;
          const int b = (a + 1) % 3;
          o[b] = grid.info.bounds.lower[b] + grid.info.cell_size[b] * float(rng() % grid.info.res[b]);
          cmp.fire(list, packed, Ray{o, d, 0.0f, kInfinity}, scratch);
        }
        INFO("first difference: " << cmp.first);
        CHECK(cmp.hits > cmp.rays / 10);
        CHECK(cmp.differ == 0);
      }
    }
  }
}

TEST_CASE("cell blocks: sphere cells are packed only when asked, their lanes holding the list's spheres in order") {
  const Database db = make_database(load_scene({"balls:3", 0}));
  const Grid grid = build_grid(db);
  const CellBlocks triangles_only = build_cell_blocks(db, grid, 1);
  CHECK(triangles_only.sphere_start.empty());  // svm's paged layout holds no sphere blocks
  CHECK(triangles_only.sphere_blocks.empty());
  const CellBlocks cb = build_cell_blocks(db, grid, 1, PackKinds::kTrianglesAndSpheres);
  const std::uint32_t cells = grid.leaf_cells();
  REQUIRE(cb.sphere_start.size() == std::size_t(cells) + 1);
  REQUIRE(cb.sphere_start.back() == cb.sphere_blocks.size());
  CHECK(cb.blocks.size() == triangles_only.blocks.size());
  std::size_t packed = 0;
  for (std::uint32_t c = 0; c < cells; ++c) {
    const std::uint32_t n = grid.cell_start[c + 1] - grid.cell_start[c];
    const bool all_spheres = lists_only_spheres(db, grid, c);
    const std::uint32_t blocks = cb.sphere_start[c + 1] - cb.sphere_start[c];
    REQUIRE(blocks == (all_spheres ? (n + kBlockLanes - 1) / kBlockLanes : 0));
    if (!all_spheres) continue;
    ++packed;
    CHECK(cb.start[c] == cb.start[c + 1]);  // never packed twice
    for (std::uint32_t i = 0; i < n; ++i) {
      const SphereBlock& b = cb.sphere_blocks[cb.sphere_start[c] + i / kBlockLanes];
      const std::uint32_t l = i % kBlockLanes, id = grid.cell_primitives[grid.cell_start[c] + i];
      REQUIRE(b.primitive[l] == id);
      for (int a = 0; a < 3; ++a) REQUIRE(same_bits(b.center[a][l], db.primitives[id].data[a]));
      REQUIRE(same_bits(b.radius[l], db.primitives[id].radius()));
    }
  }
  CHECK(packed > 0);
}

TEST_CASE("cell blocks: packed sphere cells give bit-identical hits at any scale, for grazing rays and from inside") {
  // The float cull must never drop a sphere the exact test would hit: rays
  // aimed at centres, grazing the silhouette (the line's distance within a
  // few ulps of the radius), starting inside a sphere or on its surface,
  // and segments ending near a surface, on scenes scaled from 1e-6 to 1e6
  // and moved by 1e4.
  struct Case {
    const char* spec;
    double scale, shift;
  };
  for (const Case& c : {Case{"balls:3", 1, 0}, Case{"balls:3", 1e-6, 0}, Case{"balls:3", 1e6, 0},
                        Case{"balls:3", 1, 1e4}, Case{"shells:1", 1, 0}}) {
    CAPTURE(c.spec);
    CAPTURE(c.scale);
    CAPTURE(c.shift);
    Scene scene = load_scene({c.spec, 0});
    transform_scene(scene, SceneTransform{c.scale, {c.shift, -c.shift, c.shift}});
    const Database db = make_database(scene);
    const Grid grid = build_grid(db);
    const DirectView list(db, grid);
    const CellBlocks cb = build_cell_blocks(db, grid, 1, PackKinds::kTrianglesAndSpheres);
    REQUIRE(!cb.sphere_blocks.empty());
    const DirectView packed(db, grid, &cb);
    std::vector<std::uint32_t> spheres;
    for (std::uint32_t i = 0; i < db.primitives.size(); ++i)
      if (db.primitives[i].kind == PrimitiveKind::kSphere) spheres.push_back(i);
    TraversalScratch scratch;
    Comparison cmp;
    Rng rng(11);
    const Bounds3 box = grown(db.bounds, 0.3f);
    for (int i = 0; i < 4000; ++i) {
      const Primitive& p = db.primitives[spheres[rng() % spheres.size()]];
      const Vec3 centre = p.center();
      const float r = std::fabs(p.radius());
      Vec3 o = random_in(rng, box), d = random_unit(rng);
      switch (i % 5) {
        case 0: d = centre - o; break;  // at the centre
        case 1: {                       // grazing: aimed at a point on the silhouette
          const Vec3 to = normalize(centre - o);
          Vec3 side = normalize(cross(to, random_unit(rng)));
          d = centre + side * (r * (1.0f + uniform(rng, -4e-7f, 4e-7f))) - o;
          break;
        }
        case 2: o = centre + random_unit(rng) * (r * uniform(rng, 0.0f, 0.999f)); break;  // inside
        case 3: o = centre + random_unit(rng) * r; break;                                 // on the surface
        default: break;
      }
      cmp.fire(list, packed, Ray{o, d, 0.0f, kInfinity}, scratch);
      // A segment ending near the aimed surface (shadow rays, and the cull's t interval).
      cmp.fire(list, packed, Ray{o, d, 0.0f, uniform(rng, 0.9f, 1.1f)}, scratch);
    }
    INFO("first difference: " << cmp.first);
    CHECK(cmp.hits > cmp.rays / 10);
    CHECK(cmp.differ == 0);
  }
}

TEST_CASE("cell blocks: sphere blocks stay within four times the blocks of each sphere once, longest cells first") {
  // Large overlapping spheres (SPD shells) are listed in many cells each:
  // packing every all-sphere cell would copy them far past the budget.
  const Database db = make_database(load_scene({"shells:3", 0}));
  const Grid grid = build_grid(db);
  std::uint64_t spheres = 0;
  for (const Primitive& p : db.primitives) spheres += p.kind == PrimitiveKind::kSphere;
  const std::uint64_t budget = 4 * ((spheres + kBlockLanes - 1) / kBlockLanes);
  const CellBlocks cb = build_cell_blocks(db, grid, 1, PackKinds::kTrianglesAndSpheres);
  REQUIRE(!cb.sphere_blocks.empty());
  CHECK(cb.sphere_blocks.size() <= budget);
  // Every eligible cell left out is longer than the budget left after the
  // cells at least as long were packed: the greedy longest-first choice.
  std::uint64_t eligible_blocks = 0;
  std::vector<std::pair<std::uint32_t, bool>> eligible;  // (blocks, packed)
  for (std::uint32_t c = 0; c < grid.leaf_cells(); ++c) {
    const std::uint32_t n = grid.cell_start[c + 1] - grid.cell_start[c];
    const bool all_spheres = lists_only_spheres(db, grid, c);
    if (!all_spheres) continue;
    const std::uint32_t blocks = (n + kBlockLanes - 1) / kBlockLanes;
    eligible_blocks += blocks;
    eligible.emplace_back(blocks, cb.sphere_start[c + 1] != cb.sphere_start[c]);
  }
  REQUIRE(eligible_blocks > budget);  // the scene does exceed the cap
  for (const auto& [blocks, packed] : eligible) {
    if (packed) continue;
    std::uint64_t longer_or_equal = 0;  // blocks packed in cells at least as long (taken before it)
    for (const auto& [b2, p2] : eligible) longer_or_equal += (p2 && b2 >= blocks) ? b2 : 0;
    CHECK(longer_or_equal + blocks > budget);
  }
}

TEST_CASE("cell blocks: rays leaving a surface and rays near a huge triangle finish alike in packed and listed cells") {
  // The candidates the block finish hands to scalar steps: the surface a ray
  // starts on (an unreliable t at the origin: refused), and a triangle far
  // larger than the distance to its hit (an unreliable t beyond it: taken
  // in double).
  SUBCASE("rays spawned from a hit never take their own triangle") {
    const Built b(load_scene({"teapot:6", 0}));
    const DirectView list = b.view(), packed = b.packed_view();
    TraversalScratch scratch;
    Comparison cmp;
    Rng rng(11);
    const Bounds3 box = grown(b.db.bounds, 0.3f);
    std::size_t spawned = 0, self_hits = 0;
    for (int i = 0; i < 3000; ++i) {
      const Vec3 o = random_in(rng, box);
      const Ray ray{o, centre_of(b.db.primitives[rng() % b.db.primitives.size()]) - o, 0.0f, kInfinity};
      Hit h;
      if (!intersect_closest(list, ray, h, scratch)) continue;
      // The tracer's spawn: off the error bound, to the side the ray leaves on.
      const HitPoint hp = hit_point(b.db.primitives[h.primitive], ray, h);
      const Vec3 d = random_unit(rng);
      const Ray leave{offset_ray_origin(hp, dot(d, hp.normal) < 0.0f ? -hp.normal : hp.normal), d, 0.0f, kInfinity};
      cmp.fire(list, packed, leave, scratch);
      ++spawned;
      Hit again;
      if (intersect_closest(packed, leave, again, scratch)) self_hits += again.primitive == h.primitive;
    }
    INFO("first difference: " << cmp.first);
    CHECK(spawned > 2000);
    CHECK(self_hits == 0);
    CHECK(cmp.differ == 0);
  }
  SUBCASE("a ground 1e8 across seen from 1e-2 above is hit where its plane is") {
    Scene s;
    const float g = 1e8f;
    add_quad(s, {-g, 0, -g}, {g, 0, -g}, {g, 0, g}, {-g, 0, g});
    for (int i = 0; i < 20; ++i)
      for (int k = 0; k < 20; ++k) {
        const float x = 1e-2f * float(i - 10), z = 1e-2f * float(k - 10), y = 2e-3f + 1e-3f * float((i + k) % 7);
        add_quad(s, {x, y, z}, {x + 4e-3f, y, z}, {x + 4e-3f, y + 2e-3f, z + 4e-3f}, {x, y + 2e-3f, z + 4e-3f});
      }
    const Built b(s);
    const DirectView list = b.view(), packed = b.packed_view();
    TraversalScratch scratch;
    Comparison cmp;
    Rng rng(12);
    std::size_t ground = 0, off_plane = 0;
    for (int i = 0; i < 4000; ++i) {
      const Vec3 o{uniform(rng, -0.1f, 0.1f), uniform(rng, 1e-3f, 2e-2f), uniform(rng, -0.1f, 0.1f)};
      Vec3 d = random_unit(rng);
      d.y = -std::fabs(d.y) - 1e-3f;
      const Ray ray{o, d, 0.0f, kInfinity};
      cmp.fire(list, packed, ray, scratch);
      Hit h;
      if (!intersect_closest(packed, ray, h, scratch) || h.primitive >= 2) continue;  // the ground's two triangles
      ++ground;
      const double exact = -double(o.y) / double(d.y);
      off_plane += std::fabs(double(h.t) - exact) > 1e-5 * exact;
    }
    INFO("first difference: " << cmp.first);
    CHECK(ground > 1000);
    CHECK(off_plane == 0);
    CHECK(cmp.differ == 0);
  }
}

TEST_CASE("cell blocks: skipping the triangle a spawned ray leaves changes no answer, in packed and listed cells") {
  // SurfaceFrame::leaving names the hit triangle for a ray spawned from the
  // hit to the side its direction clearly goes; the queries then skip it.
  // The full test refuses it anyway (its plane lies behind the origin), so
  // every answer is the same bit for bit, with fewer triangle tests.
  for (const char* spec : {"teapot:6", "mount:4"}) {
    CAPTURE(spec);
    const Built b(load_scene({spec, 0}));
    const DirectView list = b.view(), packed = b.packed_view();
    TraversalScratch scratch;
    Rng rng(21);
    const Bounds3 box = grown(b.db.bounds, 0.3f);
    std::size_t spawned = 0, named = 0, differ = 0;
    std::uint64_t tests_full = 0, tests_skipping = 0;
    std::string first;
    for (int i = 0; i < 3000; ++i) {
      const Vec3 o = random_in(rng, box);
      const Ray ray{o, centre_of(b.db.primitives[rng() % b.db.primitives.size()]) - o, 0.0f, kInfinity};
      Hit h;
      if (!intersect_closest(list, ray, h, scratch)) continue;
      const SurfaceFrame f = surface_frame(list, b.db.primitives[h.primitive], ray, h);
      const Vec3 d = random_unit(rng);
      const Ray leave{dot(d, f.nf) > 0.0f ? f.above : f.below, d, 0.0f, kInfinity};
      const std::uint32_t origin = f.leaving(leave);
      ++spawned;
      if (origin == kNoPrimitive) continue;
      ++named;
      CHECK(origin == h.primitive);
      for (const DirectView* v : {&list, &packed}) {
        Hit a, c;
        scratch.stats = {};
        const bool fa = intersect_closest(*v, leave, a, scratch), aa = intersect_any(*v, leave, scratch);
        tests_full += scratch.stats.triangle_tests;
        scratch.stats = {};
        const bool fc = intersect_closest(*v, leave, c, scratch, origin), ac = intersect_any(*v, leave, scratch, origin);
        tests_skipping += scratch.stats.triangle_tests;
        const bool same = fa == fc && aa == ac && a.primitive == c.primitive && same_bits(a.t, c.t) &&
                          same_bits(a.u, c.u) && same_bits(a.v, c.v);
        if (!same && differ++ == 0) first = str(leave) + ": full " + str(a) + ", skipping " + str(c);
      }
    }
    INFO("first difference: " << first);
    CHECK(spawned > 2000);
    CHECK(named > spawned * 9 / 10);  // all but grazing directions
    CHECK(differ == 0);
    CHECK(tests_skipping < tests_full);
  }
}

TEST_CASE("cell blocks: a ray names the triangle it leaves only on the side its origin was put") {
  const Built b(load_scene({"teapot:3", 0}));
  const DirectView v = b.view();
  TraversalScratch scratch;
  const Ray eye{b.db.bounds.upper + Vec3{1, 1, 1}, b.db.bounds.center() - (b.db.bounds.upper + Vec3{1, 1, 1}), 0.0f,
                kInfinity};
  Hit h;
  REQUIRE(intersect_closest(v, eye, h, scratch));
  const SurfaceFrame f = surface_frame(v, b.db.primitives[h.primitive], eye, h);
  REQUIRE(f.triangle == h.primitive);
  CHECK(f.leaving(Ray{f.above, f.nf, 0.0f, kInfinity}) == h.primitive);
  CHECK(f.leaving(Ray{f.below, -f.nf, 0.0f, kInfinity}) == h.primitive);
  // A shadow ray to a light behind the surface starts above and crosses it.
  CHECK(f.leaving(Ray{f.above, -f.nf, 0.0f, 1.0f}) == kNoPrimitive);
  CHECK(f.leaving(Ray{f.below, f.nf, 0.0f, kInfinity}) == kNoPrimitive);
  // Grazing: no side is clear.
  const Vec3 along = normalize(cross(f.nf, std::fabs(f.nf.x) < 0.9f ? Vec3{1, 0, 0} : Vec3{0, 1, 0}));
  CHECK(f.leaving(Ray{f.above, along, 0.0f, kInfinity}) == kNoPrimitive);
  // An origin elsewhere than the two spawn points.
  CHECK(f.leaving(Ray{f.p + f.nf, f.nf, 0.0f, kInfinity}) == kNoPrimitive);
  // A sphere is curved: a ray leaving it may meet it again.
  const Built s(load_scene({"balls:1", 0}));
  const DirectView sv = s.view();
  const Ray at{s.db.bounds.upper + Vec3{1, 1, 1}, s.db.bounds.center() - (s.db.bounds.upper + Vec3{1, 1, 1}), 0.0f,
               kInfinity};
  Hit sh;
  REQUIRE(intersect_closest(sv, at, sh, scratch));
  REQUIRE(s.db.primitives[sh.primitive].kind == PrimitiveKind::kSphere);
  const SurfaceFrame sf = surface_frame(sv, s.db.primitives[sh.primitive], at, sh);
  CHECK(sf.leaving(Ray{sf.above, sf.nf, 0.0f, kInfinity}) == kNoPrimitive);
}
