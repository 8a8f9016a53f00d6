// Tests of the uniform grid and its 3D-DDA traversal (grid.h, traverse.h),
// through the public API only: build a Database and a Grid, query them with
// intersect_closest / intersect_any over a DirectView, and compare with
//  - a brute-force closest hit over every primitive using the same
//    single-primitive tests (intersect.h): the grid must return exactly the
//    same t (bit for bit), since it may only skip primitives that cannot be
//    hit, never change the arithmetic;
//  - Embree (embree_scene.h), an independent intersector, within a relative
//    t tolerance;
//  - known answers (closed meshes must not leak, scaled scenes hit the same
//    primitive, ...).
// The SPD reference scenes are checked with validate_grid and a ray budget
// small enough for CI (64x64 primary and 20000 random rays instead of
// 512x512 and 400000).
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "core/database.h"
#include "core/direct_view.h"
#include "core/embree_scene.h"
#include "core/grid.h"
#include "core/intersect.h"
#include "core/math.h"
#include "core/nff.h"
#include "core/scene.h"
#include "core/scene_source.h"
#include "core/spd.h"
#include "core/traverse.h"
#include "core/validate.h"
#include "scenes_dir.h"

namespace {

using namespace raynode::core;
using Rng = std::mt19937_64;

// ---------------------------------------------------------------------------
// Helpers

std::string str(const Vec3& v) {
  char b[128];
  std::snprintf(b, sizeof b, "(%.9g, %.9g, %.9g)", v.x, v.y, v.z);
  return b;
}

std::string str(const Ray& r) {
  char b[64];
  std::snprintf(b, sizeof b, " tmin=%.9g tmax=%.9g", r.tmin, r.tmax);
  return "o=" + str(r.origin) + " d=" + str(r.direction) + b;
}

std::string str(const Hit& h) {
  if (!h.found()) return "miss";
  char b[64];
  std::snprintf(b, sizeof b, "prim %u t=%.9g", h.primitive, h.t);
  return b;
}

float uniform(Rng& rng, float lo, float hi) { return std::uniform_real_distribution<float>(lo, hi)(rng); }

Vec3 random_in(Rng& rng, const Bounds3& b) {
  return {uniform(rng, b.lower.x, b.upper.x), uniform(rng, b.lower.y, b.upper.y),
          uniform(rng, b.lower.z, b.upper.z)};
}

Vec3 random_unit(Rng& rng) {
  std::normal_distribution<float> n(0.0f, 1.0f);
  for (;;) {
    const Vec3 v{n(rng), n(rng), n(rng)};
    if (length(v) > 1e-3f) return normalize(v);
  }
}

Bounds3 grown(Bounds3 b, float fraction) {
  const Vec3 g = b.extent() * fraction;
  b.lower -= g;
  b.upper += g;
  return b;
}

// Database + grid, built in place (a DirectView points into both).
struct Built {
  Database db;
  Grid grid;
  explicit Built(const Scene& s, const GridParams& gp = {}, const DatabaseParams& dp = {})
      : db(make_database(s, dp)), grid(build_grid(db, gp)) {}
  DirectView view() const { return DirectView(db, grid); }
};

GridParams forced(int x, int y, int z) {
  GridParams p;
  p.resolution[0] = x;
  p.resolution[1] = y;
  p.resolution[2] = z;
  return p;
}

// Closest hit by testing every primitive with the single-primitive tests.
Hit brute_closest(const Database& db, const Ray& ray) {
  Hit hit;
  hit.t = ray.tmax;
  const WatertightRay w(ray.direction);
  for (std::uint32_t i = 0; i < db.primitives.size(); ++i) {
    const Primitive& p = db.primitives[i];
    switch (p.kind) {
      case PrimitiveKind::kTriangle: {
        TriangleHit th;
        if (intersect_triangle(ray, w, p.vertex(0), p.vertex(1), p.vertex(2), hit.t, th))
          hit = Hit{th.t, i, th.u, th.v};
        break;
      }
      case PrimitiveKind::kSphere: {
        float t;
        if (intersect_sphere(ray, p.center(), p.radius(), hit.t, t)) hit = Hit{t, i, 0, 0};
        break;
      }
      case PrimitiveKind::kCone: {
        float t;
        if (intersect_cone(ray, p.cone_base(), p.cone_base_radius(), p.cone_apex(), p.cone_apex_radius(), hit.t,
                           t))
          hit = Hit{t, i, 0, 0};
        break;
      }
    }
  }
  if (!hit.found()) hit = Hit{};
  return hit;
}

// Counts failures and keeps the first few descriptions for the report.
struct Failures {
  std::size_t count = 0;
  std::string first;
  void add(const std::string& what) {
    if (count++ < 5) first += "\n  " + what;
  }
};

// Distance from the point a + s (b - a), s in [0,1], to the ray (t >= 0):
// convex in s, so minimised by ternary search. In double.
double ray_segment_distance(const Ray& r, const Vec3& a, const Vec3& b) {
  const double o[3] = {r.origin.x, r.origin.y, r.origin.z};
  const double d[3] = {r.direction.x, r.direction.y, r.direction.z};
  const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  auto dist2 = [&](double s) {
    double q[3], w[3];
    for (int i = 0; i < 3; ++i) q[i] = double(a[i]) + s * (double(b[i]) - double(a[i])) - o[i];
    const double t = std::max(0.0, (q[0] * d[0] + q[1] * d[1] + q[2] * d[2]) / dd);
    for (int i = 0; i < 3; ++i) w[i] = q[i] - t * d[i];
    return w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
  };
  double lo = 0, hi = 1;
  for (int i = 0; i < 100; ++i) {
    const double m1 = lo + (hi - lo) / 3, m2 = hi - (hi - lo) / 3;
    if (dist2(m1) < dist2(m2)) {
      hi = m2;
    } else {
      lo = m1;
    }
  }
  return std::sqrt(std::min({dist2(0), dist2(1), dist2(0.5 * (lo + hi))}));
}

// True when the ray passes no triangle edge or vertex, no sphere silhouette,
// and starts on no triangle or sphere, closer than `margin` (world units):
// then every correct intersector must give the same hit or miss, whereas
// on a graze Embree's robust mode and its float sphere test may take either
// side (and the oracle's interval is closed, [tmin, tmax], where ours is
// open). Cones are not checked: the oracle calls our cone test.
bool decisive(const Database& db, const Ray& ray, float margin) {
  for (const Primitive& p : db.primitives) {
    if (p.kind == PrimitiveKind::kTriangle) {
      for (int k = 0; k < 3; ++k)
        if (ray_segment_distance(ray, p.vertex(k), p.vertex((k + 1) % 3)) < margin) return false;
      // Origin on (or within margin of) the face.
      const Vec3 n = cross(p.vertex(1) - p.vertex(0), p.vertex(2) - p.vertex(0));
      const float ln = length(n);
      if (ln > 0.0f && std::fabs(dot(ray.origin - p.vertex(0), n)) / ln < margin) {
        const Vec3 q = ray.origin - n * (dot(ray.origin - p.vertex(0), n) / (ln * ln));
        bool inside = true;
        for (int k = 0; k < 3; ++k)
          inside &= dot(cross(p.vertex((k + 1) % 3) - p.vertex(k), q - p.vertex(k)), n) >= 0.0f;
        if (inside) return false;
      }
    } else if (p.kind == PrimitiveKind::kSphere) {
      const float r = std::fabs(p.radius());
      if (std::fabs(length(ray.origin - p.center()) - r) < margin) return false;
      if (std::fabs(ray_segment_distance(ray, p.center(), p.center()) - r) < margin) return false;
    }
  }
  return true;
}

// Fires rays through the grid and checks each
//  - against brute force: same hit or miss and bit-identical t, always;
//  - against Embree: same hit or miss and t within 1e-4 relative, for the
//    decisive rays (see `decisive`);
//  - intersect_any against intersect_closest.
struct RayChecker {
  const Built& b;
  EmbreeScene embree;
  TraversalScratch scratch;
  Failures vs_brute, vs_embree, any;
  std::size_t rays = 0, hits = 0;
  float margin;

  explicit RayChecker(const Built& built)
      : b(built), embree(built.db), margin(1e-5f * length(built.grid.info.bounds.extent())) {}

  Hit check(const Ray& ray) {
    ++rays;
    Hit g;
    const bool found = intersect_closest(b.view(), ray, g, scratch);
    hits += found;
    const Hit r = brute_closest(b.db, ray);
    if (found != g.found() || g.found() != r.found() || (found && g.t != r.t))
      vs_brute.add(str(ray) + ": grid " + str(g) + ", brute force " + str(r));
    Hit e;
    const bool he = embree.intersect_closest(ray, e);
    const float scale = std::max(std::fabs(g.t), std::fabs(e.t));
    if ((he != found || (found && !(std::fabs(g.t - e.t) <= 1e-4f * scale))) && decisive(b.db, ray, margin))
      vs_embree.add(str(ray) + ": grid " + str(g) + ", Embree " + str(he ? e : Hit{}));
    if (intersect_any(b.view(), ray, scratch) != found) any.add(str(ray) + ": any-hit disagrees with " + str(g));
    return g;
  }

  void require_clean() {
    INFO("rays " << rays << ", hits " << hits);
    INFO("grid vs brute force:" << vs_brute.first);
    CHECK(vs_brute.count == 0);
    INFO("grid vs Embree:" << vs_embree.first);
    CHECK(vs_embree.count == 0);
    INFO("any vs closest:" << any.first);
    CHECK(any.count == 0);
  }
};

// Random triangles, spheres and open cones of about `size` in [-1,1]^3.
Scene random_scene(std::uint64_t seed, int triangles, int spheres, int cones, float size) {
  Rng rng(seed);
  Scene s;
  const Bounds3 box{{-1, -1, -1}, {1, 1, 1}};
  for (int i = 0; i < triangles; ++i) {
    const Vec3 c = random_in(rng, box);
    const Vec3 v[3] = {c + random_unit(rng) * size, c + random_unit(rng) * size, c + random_unit(rng) * size};
    s.add_polygon(v, 3);
  }
  for (int i = 0; i < spheres; ++i) s.add_sphere({random_in(rng, box), size * uniform(rng, 0.2f, 1.0f)});
  for (int i = 0; i < cones; ++i) {
    const Vec3 base = random_in(rng, box);
    s.add_cone({base, size * uniform(rng, 0.1f, 0.6f), base + random_unit(rng) * (2 * size),
                size * uniform(rng, 0.0f, 0.6f)});
  }
  return s;
}

// A point inside the primitive (triangle centroid, sphere centre, cone axis
// midpoint): a ray aimed at it crosses the surface away from any edge.
Vec3 centre_of(const Primitive& p) {
  switch (p.kind) {
    case PrimitiveKind::kTriangle: return (p.vertex(0) + p.vertex(1) + p.vertex(2)) * (1.0f / 3.0f);
    case PrimitiveKind::kSphere: return p.center();
    case PrimitiveKind::kCone: return (p.cone_base() + p.cone_apex()) * 0.5f;
  }
  return {};
}

void add_quad(Scene& s, const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const Vec3 v[4] = {a, b, c, d};
  s.add_polygon(v, 4);
}

// Grid vertex coordinate i (0..res) on axis a, as GridInfo::cell_bounds gives it.
float grid_plane(const GridInfo& g, int a, int i) {
  return i == g.res[a] ? g.bounds.upper[a] : g.bounds.lower[a] + float(i) * g.cell_size[a];
}

// Rays along cell edges, from grid vertices, and inside cell planes.
void fire_grid_aligned_rays(RayChecker& chk, std::uint64_t seed) {
  const GridInfo& g = chk.b.grid.info;
  Rng rng(seed);
  const Vec3 ext = g.bounds.extent();
  for (int k = 0; k <= g.res[2]; ++k)
    for (int j = 0; j <= g.res[1]; ++j)
      for (int i = 0; i <= g.res[0]; ++i) {
        const Vec3 v{grid_plane(g, 0, i), grid_plane(g, 1, j), grid_plane(g, 2, k)};
        // Axis-parallel rays along the cell edge lines, from outside the grid.
        for (int a = 0; a < 3; ++a)
          for (int sgn : {-1, 1}) {
            Vec3 o = v, d{0, 0, 0};
            o[a] = sgn > 0 ? g.bounds.lower[a] - 0.25f * ext[a] : g.bounds.upper[a] + 0.25f * ext[a];
            d[a] = float(sgn);
            chk.check({o, d, 0.0f, kInfinity});
          }
        // From the vertex itself (inside, or on the boundary pointing in and
        // out) in the 26 directions that keep to cell edges, face diagonals
        // and cell diagonals (through further grid vertices).
        for (int dz = -1; dz <= 1; ++dz)
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              if (!dx && !dy && !dz) continue;
              const Vec3 d{dx * g.cell_size.x, dy * g.cell_size.y, dz * g.cell_size.z};
              chk.check({v, d, 0.0f, kInfinity});
            }
      }
  // Rays lying in cell planes (one zero direction component), starting
  // inside and outside the grid.
  const Bounds3 around = grown(g.bounds, 0.2f);
  for (int a = 0; a < 3; ++a)
    for (int i = 0; i <= g.res[a]; ++i)
      for (int n = 0; n < 40; ++n) {
        Vec3 o = random_in(rng, around);
        o[a] = grid_plane(g, a, i);
        Vec3 d = random_unit(rng);
        d[a] = 0.0f;
        if (dot(d, d) == 0.0f) continue;
        chk.check({o, d, 0.0f, kInfinity});
      }
}

// A random scene plus primitives placed on the cell planes of its grid at
// resolution `res`: quads in cell planes with corners at grid vertices,
// spheres centred on grid vertices, triangles with an edge on a cell edge.
Scene scene_on_grid_planes(const int res[3]) {
  Scene s = random_scene(7, 150, 15, 8, 0.15f);
  const Built first(s, forced(res[0], res[1], res[2]));
  const GridInfo& g = first.grid.info;
  auto P = [&](int i, int j, int k) { return Vec3{grid_plane(g, 0, i), grid_plane(g, 1, j), grid_plane(g, 2, k)}; };
  add_quad(s, P(1, 1, 2), P(4, 1, 2), P(4, 3, 2), P(1, 3, 2));  // in plane z = z_2
  add_quad(s, P(2, 1, 1), P(2, 3, 1), P(2, 3, 4), P(2, 1, 4));  // in plane x = x_2
  add_quad(s, P(1, 2, 1), P(1, 2, 3), P(3, 2, 3), P(3, 2, 1));  // in plane y = y_2
  add_quad(s, P(3, 3, 3), P(4, 3, 3), P(4, 4, 3), P(3, 4, 3));  // one cell face exactly
  const float r = 0.5f * std::min({g.cell_size.x, g.cell_size.y, g.cell_size.z});
  s.add_sphere({P(1, 1, 1), r});
  s.add_sphere({P(3, 2, 4), r});
  const Vec3 tri[3] = {P(1, 3, 1), P(3, 3, 1), P(2, 4, 3)};  // edge along a cell edge line
  s.add_polygon(tri, 3);
  return s;
}

}  // namespace

// ---------------------------------------------------------------------------
// Reference and generated scenes against Embree

TEST_CASE("grid: every SPD reference scene agrees with Embree (zero mismatches)") {
  RAYNODE_REQUIRE_SCENES(dir);
  namespace fs = std::filesystem;
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir / "spd")) {
    const std::string name = e.path().filename().string();
    if (name.ends_with(".nff") || name.ends_with(".nff.gz")) files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  REQUIRE(files.size() >= 18);
  for (const fs::path& f : files) {
    CAPTURE(f.filename().string());
    const Scene scene = read_nff(f.string());
    const Database db = make_database(scene);
    const Grid grid = build_grid(db);
    const EmbreeScene embree(db);
    ValidateParams vp;
    vp.width = 64;
    vp.height = 64;
    vp.random_rays = 20000;
    const ValidateReport rep = validate_grid(db, grid, embree, vp);
    std::string examples;
    for (const MismatchExample& m : rep.examples)
      examples += "\n  " + m.set + " " + str(m.ray) + ": grid " + str(m.grid) + ", Embree " + str(m.embree);
    INFO("mismatching rays:" << examples);
    CHECK(rep.total.mismatches() == 0);
    CHECK(rep.primary.grid_hits > 0);
    CHECK(rep.random.grid_hits > rep.random.rays / 10);
    CHECK(rep.secondary.rays > 0);
  }
}

TEST_CASE("grid: generated scenes, tessellated and curved, agree with Embree (zero mismatches)") {
  const struct {
    const char* spec;
    int tessellate;
  } cases[] = {{"mount:1", 1}, {"rings:1", 2}, {"balls:1", 2}, {"teapot:3", 0},
               {"tetra:4", 0}, {"rings:2", 0}, {"balls:2", 0}, {"mount:2", 0}};
  for (const auto& c : cases) {
    CAPTURE(c.spec);
    CAPTURE(c.tessellate);
    const Scene scene = load_scene({c.spec, c.tessellate});
    const Database db = make_database(scene);
    if (c.tessellate > 0) CHECK(db.counts().spheres + db.counts().cones == 0);
    const Grid grid = build_grid(db);
    const EmbreeScene embree(db);
    ValidateParams vp;
    vp.width = 64;
    vp.height = 64;
    vp.random_rays = 20000;
    const ValidateReport rep = validate_grid(db, grid, embree, vp);
    std::string examples;
    for (const MismatchExample& m : rep.examples)
      examples += "\n  " + m.set + " " + str(m.ray) + ": grid " + str(m.grid) + ", Embree " + str(m.embree);
    INFO("mismatching rays:" << examples);
    CHECK(rep.total.mismatches() == 0);
    CHECK(rep.primary.grid_hits > 0);
    CHECK(rep.random.grid_hits > rep.random.rays / 10);
  }
}

TEST_CASE("grid: random mixed scenes at several densities agree with brute force and Embree") {
  const Scene s = random_scene(3, 400, 40, 20, 0.2f);
  for (float density : {0.25f, 2.0f, 16.0f}) {
    CAPTURE(density);
    GridParams gp;
    gp.density = density;
    const Built b(s, gp);
    RayChecker chk(b);
    Rng rng(11);
    const Bounds3 around = grown(b.db.bounds, 0.3f);
    for (int i = 0; i < 4000; ++i) {
      const Vec3 o = random_in(rng, around);
      // Half aimed at a random primitive's centre, half random.
      Vec3 d = random_unit(rng);
      if (i % 2) {
        const Vec3 to = centre_of(b.db.primitives[rng() % b.db.primitives.size()]) - o;
        if (length(to) > 1e-3f) d = to;
      }
      chk.check({o, d, 0.0f, kInfinity});
    }
    CHECK(chk.hits > chk.rays / 4);
    chk.require_clean();
  }
}

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
    CHECK(h.t == brute_closest(b.db, up).t);
    const Ray down{{after, 2.5f, 2.5f}, -d, 0.0f, kInfinity};
    REQUIRE(intersect_closest(b.view(), down, h, scratch));
    CHECK(b.db.primitives[h.primitive].shape == 3);
    CHECK(h.t == brute_closest(b.db, down).t);
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
  const Hit brute = brute_closest(b.db, ray);
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
  CHECK(h.t == brute_closest(b2.db, ray).t);
  CHECK(h.t > 7.0f);
}

// ---------------------------------------------------------------------------
// Closed meshes must not leak

TEST_CASE("grid: rays from inside a closed tessellated sphere never escape, even through shared vertices") {
  const Vec3 centre{0.37f, -1.25f, 2.5f};
  const float radius = 1.3f;
  for (int resolution : {1, 2, 3, 5, 8}) {
    CAPTURE(resolution);
    Scene s;
    s.add_sphere({centre, radius});
    tessellate_scene(s, resolution);
    for (GridParams gp : {GridParams{}, forced(1, 1, 1), forced(7, 7, 7)}) {
      CAPTURE(gp.resolution[0]);
      const Built b(s, gp);
      REQUIRE(b.db.primitives.size() == std::size_t(12 * resolution * resolution));
      TraversalScratch scratch;
      Failures escaped;
      std::size_t rays = 0;
      auto fire = [&](const Vec3& o, const Vec3& target) {
        const Ray ray{o, target - o, 0.0f, kInfinity};
        if (!is_valid_ray(ray)) return;
        ++rays;
        Hit h;
        const bool hit = intersect_closest(b.view(), ray, h, scratch);
        const bool any = intersect_any(b.view(), ray, scratch);
        if (!hit || !any) {
          escaped.add(str(ray) + (hit ? " (any-hit missed)" : " escaped"));
        } else if (!(length(ray.at(h.t) - centre) <= radius * 1.0001f)) {
          escaped.add(str(ray) + ": hit outside the sphere at " + str(ray.at(h.t)));
        }
      };
      Rng rng(resolution);
      std::vector<Vec3> origins = {centre};
      for (int i = 0; i < 40; ++i) origins.push_back(centre + random_unit(rng) * (0.5f * radius * uniform(rng, 0, 1)));
      for (const Vec3& o : origins) {
        for (const Primitive& p : b.db.primitives) {
          const Vec3 v0 = p.vertex(0), v1 = p.vertex(1), v2 = p.vertex(2);
          fire(o, v0);  // shared vertices
          fire(o, v1);
          fire(o, v2);
          fire(o, (v0 + v1) * 0.5f);  // shared edges
          fire(o, (v1 + v2) * 0.5f);
          fire(o, (v2 + v0) * 0.5f);
        }
        for (int i = 0; i < 200; ++i) fire(o, o + random_unit(rng));
      }
      INFO("escaping rays:" << escaped.first);
      CHECK(rays > 1000);
      CHECK(escaped.count == 0);
    }
  }
}

TEST_CASE("grid: rays from inside a closed two-triangles-per-face cube never escape through diagonals or vertices") {
  // Axis-aligned and rotated, at several grid resolutions.
  const float c = std::cos(0.5f), sn = std::sin(0.5f), c2 = std::cos(0.3f), s2 = std::sin(0.3f);
  auto rotate = [&](Vec3 p) {
    p = {c * p.x - sn * p.y, sn * p.x + c * p.y, p.z};
    return Vec3{p.x, c2 * p.y - s2 * p.z, s2 * p.y + c2 * p.z};
  };
  for (bool rotated : {false, true}) {
    CAPTURE(rotated);
    const Vec3 offset{10.25f, -3.5f, 0.75f};
    Vec3 v[8];
    for (int i = 0; i < 8; ++i) {
      const Vec3 p{(i & 1) ? 1.0f : -1.0f, (i & 2) ? 1.0f : -1.0f, (i & 4) ? 1.0f : -1.0f};
      v[i] = (rotated ? rotate(p) : p) + offset;
    }
    // Faces as corner indices in order around the face.
    const int faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    Scene s;
    for (const auto& f : faces) {
      const Vec3 t1[3] = {v[f[0]], v[f[1]], v[f[2]]};
      const Vec3 t2[3] = {v[f[0]], v[f[2]], v[f[3]]};
      s.add_polygon(t1, 3);
      s.add_polygon(t2, 3);
    }
    for (GridParams gp : {GridParams{}, forced(1, 1, 1), forced(2, 2, 2), forced(4, 4, 4), forced(5, 3, 7)}) {
      CAPTURE(gp.resolution[0]);
      const Built b(s, gp);
      REQUIRE(b.db.primitives.size() == 12);
      TraversalScratch scratch;
      Failures escaped;
      std::size_t rays = 0;
      Rng rng(23);
      std::vector<Vec3> targets(std::begin(v), std::end(v));
      for (const auto& f : faces) {
        targets.push_back((v[f[0]] + v[f[2]]) * 0.5f);  // face centre, on the diagonal
        for (int k = 0; k < 4; ++k) targets.push_back((v[f[k]] + v[f[(k + 1) % 4]]) * 0.5f);  // edge midpoints
        for (int k = 0; k < 10; ++k) {
          const float a = uniform(rng, 0, 1);
          targets.push_back(v[f[0]] + (v[f[2]] - v[f[0]]) * a);  // along the shared diagonal
        }
      }
      std::vector<Vec3> origins = {offset};
      for (int i = 0; i < 60; ++i) {
        const Vec3 p{uniform(rng, -0.99f, 0.99f), uniform(rng, -0.99f, 0.99f), uniform(rng, -0.99f, 0.99f)};
        origins.push_back((rotated ? rotate(p) : p) + offset);
      }
      for (const Vec3& o : origins)
        for (const Vec3& t : targets) {
          const Ray ray{o, t - o, 0.0f, kInfinity};
          ++rays;
          Hit h;
          if (!intersect_closest(b.view(), ray, h, scratch)) escaped.add(str(ray) + " escaped");
          if (!intersect_any(b.view(), ray, scratch)) escaped.add(str(ray) + " escaped the any-hit query");
        }
      INFO("escaping rays:" << escaped.first);
      CHECK(rays > 2000);
      CHECK(escaped.count == 0);
    }
  }
}

// ---------------------------------------------------------------------------
// Scale and translation invariance

TEST_CASE("grid: scenes scaled by 1e-4 and 1e4 and moved far from the origin hit the same primitives") {
  // Well separated primitives on a lattice, so the answer cannot depend on rounding.
  Rng rng(29);
  Scene base;
  std::vector<Vec3> targets;
  for (int k = 0; k < 4; ++k)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 4; ++i) {
        const Vec3 c{float(i) - 1.5f, float(j) - 1.5f, float(k) - 1.5f};
        if ((i + j + k) % 3 == 0) {
          base.add_sphere({c, 0.25f});
        } else {
          const Vec3 t[3] = {c + random_unit(rng) * 0.3f, c + random_unit(rng) * 0.3f, c + random_unit(rng) * 0.3f};
          base.add_polygon(t, 3);
        }
        targets.push_back(c);
      }
  base.add_cone({{2.5f, 0, 0}, 0.2f, {2.5f, 0, 1}, 0.1f});
  const Built ref(base);
  // Rays from all around, aimed at primitive centres. Only rays whose answer
  // is robust are kept: the same primitive is hit when the ray is moved
  // sideways by 2e-3 (far more than any rounding of the scaled scenes), so a
  // different answer after scaling can only be the grid's fault.
  TraversalScratch scratch;
  std::vector<Ray> rays;
  std::vector<std::uint32_t> expected;
  std::size_t hits = 0;
  for (int n = 0; n < 4000; ++n) {
    const Vec3 o = random_in(rng, {{-4, -4, -4}, {4, 4, 4}});
    const Primitive& p = ref.db.primitives[rng() % ref.db.primitives.size()];
    const Vec3 target = centre_of(p);
    const Ray r{o, target - o, 0.0f, kInfinity};
    Hit h;
    intersect_closest(ref.view(), r, h, scratch);
    const Vec3 side1 = normalize(cross(r.direction, Vec3{0.3f, 0.5f, 0.8f})) * 2e-3f;
    const Vec3 side2 = normalize(cross(r.direction, side1)) * 2e-3f;
    bool robust = true;
    for (const Vec3& shift : {side1, -side1, side2, -side2}) {
      Hit hs;
      intersect_closest(ref.view(), Ray{o + shift, r.direction, 0.0f, kInfinity}, hs, scratch);
      robust &= hs.primitive == h.primitive;
    }
    if (!robust) continue;
    rays.push_back(r);
    expected.push_back(h.primitive);
    hits += h.found();
  }
  REQUIRE(rays.size() > 3000);
  REQUIRE(hits > rays.size() / 2);

  const struct {
    float scale;
    float offset;
  } cases[] = {{1e-4f, 0.0f}, {1e4f, 0.0f}, {1.0f, 1e3f}, {1e4f, 1e3f}, {1e-4f, 1e-3f}};
  for (const auto& c : cases) {
    CAPTURE(c.scale);
    CAPTURE(c.offset);
    const Vec3 off{c.offset, c.offset, c.offset};
    auto xf = [&](const Vec3& p) { return p * c.scale + off; };
    Scene s = base;
    for (Vec3& v : s.vertices) v = xf(v);
    for (Sphere& sp : s.spheres) {
      sp.center = xf(sp.center);
      sp.radius *= c.scale;
    }
    for (Cone& cn : s.cones) {
      cn.base = xf(cn.base);
      cn.apex = xf(cn.apex);
      cn.base_radius *= c.scale;
      cn.apex_radius *= c.scale;
    }
    const Built b(s);
    Failures diff;
    for (std::size_t i = 0; i < rays.size(); ++i) {
      const Ray& r = rays[i];
      const Ray rs{xf(r.origin), r.direction * c.scale, 0.0f, kInfinity};
      Hit h;
      intersect_closest(b.view(), rs, h, scratch);
      if (h.primitive != expected[i])
        diff.add(str(rs) + ": grid " + str(h) + ", unscaled primitive " + std::to_string(expected[i]));
    }
    INFO("rays with another answer:" << diff.first);
    CHECK(diff.count == 0);
  }
}

// ---------------------------------------------------------------------------
// Degenerate input

TEST_CASE("grid: triangles with coincident vertices never hit and degenerate triangles do not break the build") {
  Scene s = random_scene(31, 50, 0, 0, 0.2f);
  const std::size_t good = s.shapes.size();
  const Vec3 coincident[][3] = {
      {{0.5f, 0.1f, 0}, {0.5f, 0.1f, 0}, {0.2f, 0.7f, 0.3f}},        // repeated vertex
      {{0.3f, 0.2f, 0.1f}, {0.3f, 0.2f, 0.1f}, {0.3f, 0.2f, 0.1f}},  // a point
      {{-0.8f, -0.8f, 0.9f}, {0.8f, 0.8f, 0.9f}, {0.8f, 0.8f, 0.9f}},
      {{0.1f, -0.6f, 0.2f}, {-0.7f, 0.4f, -0.1f}, {0.1f, -0.6f, 0.2f}},
  };
  const Vec3 collinear[][3] = {
      {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}},
      {{-1, 0.5f, 0}, {1, 0.5f, 0}, {0, 0.5f, 0}},  // middle vertex last
  };
  for (const auto& d : coincident) s.add_polygon(d, 3);
  for (const auto& d : collinear) s.add_polygon(d, 3);
  // Kept (drop_degenerate = false): the grid builds and lists them.
  DatabaseParams keep;
  keep.drop_degenerate = false;
  const Built b(s, GridParams{}, keep);
  const std::size_t degenerate = std::size(coincident) + std::size(collinear);
  REQUIRE(b.db.primitives.size() == good + degenerate);
  REQUIRE(b.grid.cell_start.size() == b.grid.info.cell_count() + 1);
  CHECK(b.grid.cell_start.back() == b.grid.cell_primitives.size());
  std::vector<bool> listed(b.db.primitives.size(), false);
  for (std::uint32_t id : b.grid.cell_primitives) {
    REQUIRE(id < b.db.primitives.size());
    listed[id] = true;
  }
  CHECK(std::count(listed.begin(), listed.end(), true) == std::ptrdiff_t(listed.size()));
  // Rays aimed at points of the coincident-vertex triangles, and along their
  // edges, never report them.
  Rng rng(37);
  TraversalScratch scratch;
  Failures bad;
  std::size_t rays = 0;
  for (std::size_t i = good; i < good + std::size(coincident); ++i) {
    const Primitive& p = b.db.primitives[i];
    for (int n = 0; n < 300; ++n) {
      const float a = uniform(rng, 0, 1), c = uniform(rng, 0, 1 - a);
      const Vec3 target = p.vertex(0) + (p.vertex(1) - p.vertex(0)) * a + (p.vertex(2) - p.vertex(0)) * c;
      const Vec3 o = target + random_unit(rng) * 3.0f;
      std::vector<Ray> tries = {{o, target - o, 0.0f, kInfinity}};
      for (int k = 0; k < 3; ++k) {
        const Vec3 along = p.vertex((k + 1) % 3) - p.vertex(k);
        if (dot(along, along) > 0.0f) tries.push_back({p.vertex(k) - along, along, 0.0f, kInfinity});
      }
      for (const Ray& r : tries) {
        ++rays;
        Hit h;
        if (intersect_closest(b.view(), r, h, scratch) && h.primitive >= good) bad.add(str(r) + ": " + str(h));
        if (!intersect_closest(b.view(), r, h, scratch) && intersect_any(b.view(), r, scratch))
          bad.add(str(r) + ": any-hit found what closest did not");
      }
    }
  }
  INFO("rays hitting a degenerate triangle:" << bad.first);
  CHECK(rays >= 1500);
  CHECK(bad.count == 0);
  // Dropped by default, and counted: then no ray can meet them.
  const Database dropped = make_database(s);
  CHECK(dropped.primitives.size() == good);
  CHECK(dropped.dropped_degenerate_triangles == degenerate);
}

TEST_CASE("grid: a polygon with collinear vertices is triangulated without losing area") {
  // A 2x2 square in the plane z = 0.5 with extra vertices on every edge.
  const Vec3 poly[] = {{-1, -1, 0.5f}, {0, -1, 0.5f},  {0.5f, -1, 0.5f}, {1, -1, 0.5f}, {1, 0, 0.5f},
                       {1, 1, 0.5f},   {0.25f, 1, 0.5f}, {-1, 1, 0.5f},  {-1, 0.5f, 0.5f}, {-1, -0.5f, 0.5f}};
  const std::uint32_t n = std::size(poly);
  std::vector<std::uint32_t> tris;
  triangulate_polygon(poly, n, tris);
  double area = 0;
  for (std::size_t t = 0; t < tris.size(); t += 3) {
    const Vec3 nrm = cross(poly[tris[t + 1]] - poly[tris[t]], poly[tris[t + 2]] - poly[tris[t]]);
    CHECK(nrm.z > 0.0f);  // every piece faces like the polygon (+z), none is a sliver
    area += 0.5 * length(nrm);
  }
  CHECK(area == doctest::Approx(4.0).epsilon(1e-6));
  Scene s;
  s.add_polygon(poly, n);
  const Built b(s);
  CHECK(b.db.primitives.size() == tris.size() / 3);
  Rng rng(41);
  TraversalScratch scratch;
  std::size_t wrong = 0;
  for (int i = 0; i < 3000; ++i) {
    const Vec3 p{uniform(rng, -1.2f, 1.2f), uniform(rng, -1.2f, 1.2f), 0.5f};
    const bool inside = std::fabs(p.x) < 0.999f && std::fabs(p.y) < 0.999f;
    const bool outside = std::fabs(p.x) > 1.001f || std::fabs(p.y) > 1.001f;
    if (!inside && !outside) continue;
    const Vec3 o = p + Vec3{uniform(rng, -0.5f, 0.5f), uniform(rng, -0.5f, 0.5f), 2.0f};
    Hit h;
    wrong += intersect_closest(b.view(), Ray{o, p - o, 0.0f, kInfinity}, h, scratch) != inside;
  }
  CHECK(wrong == 0);
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
  CHECK(h.t == brute_closest(b.db, hitting).t);
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
  const Built with_near(make(true), forced(64, 4, 4));
  const Built far_only(make(false), forced(64, 4, 4));
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

TEST_CASE("grid: intersect_any agrees with intersect_closest and with Embree on many random rays") {
  const Scene s = random_scene(43, 500, 50, 30, 0.15f);
  const Built b(s);
  const EmbreeScene embree(b.db);
  Rng rng(47);
  TraversalScratch scratch;
  const Bounds3 around = grown(b.db.bounds, 0.3f);
  Failures bad;
  std::size_t hits = 0, blocked = 0;
  for (int i = 0; i < 20000; ++i) {
    const Vec3 o = random_in(rng, around);
    const Vec3 d = random_unit(rng) * uniform(rng, 0.5f, 2.0f);
    // Half are shadow rays with a finite tmax, some with tmin > 0.
    const float tmax = (i % 2) ? uniform(rng, 0.01f, 3.0f) : kInfinity;
    const float tmin = (i % 4 == 1) ? uniform(rng, 0.0f, 0.01f) : 0.0f;
    const Ray ray{o, d, tmin, tmax};
    Hit h;
    const bool closest = intersect_closest(b.view(), ray, h, scratch);
    const bool any = intersect_any(b.view(), ray, scratch);
    hits += closest;
    blocked += any && std::isfinite(tmax);
    if (closest != any) bad.add(str(ray) + ": closest " + str(h) + ", any " + std::to_string(any));
    if (closest && !(h.t > tmin && h.t < tmax)) bad.add(str(ray) + ": hit outside (tmin, tmax): " + str(h));
    if (any != embree.intersect_any(ray)) {
      // Embree's robust mode may differ on rays grazing an edge; the
      // brute-force answer decides.
      if (any != brute_closest(b.db, ray).found()) bad.add(str(ray) + ": any-hit disagrees with Embree and brute force");
    }
  }
  INFO("disagreements:" << bad.first);
  CHECK(hits > 2000);
  CHECK(blocked > 1000);
  CHECK(bad.count == 0);
}

// ---------------------------------------------------------------------------
// Concave polygons (the SPD gears faces are concave)

namespace {

struct Polygon2 {
  const char* name;
  std::vector<std::array<double, 2>> pts;
};

double shoelace(const Polygon2& p) {
  double a = 0;
  for (std::size_t i = 0; i < p.pts.size(); ++i) {
    const auto& u = p.pts[i];
    const auto& v = p.pts[(i + 1) % p.pts.size()];
    a += u[0] * v[1] - v[0] * u[1];
  }
  return 0.5 * a;
}

// Even-odd point in polygon, and distance to the outline.
bool inside(const Polygon2& p, double x, double y) {
  bool in = false;
  for (std::size_t i = 0, j = p.pts.size() - 1; i < p.pts.size(); j = i++) {
    const auto& a = p.pts[i];
    const auto& b = p.pts[j];
    if ((a[1] > y) != (b[1] > y) && x < (b[0] - a[0]) * (y - a[1]) / (b[1] - a[1]) + a[0]) in = !in;
  }
  return in;
}
double outline_distance(const Polygon2& p, double x, double y) {
  double best = 1e300;
  for (std::size_t i = 0; i < p.pts.size(); ++i) {
    const auto& a = p.pts[i];
    const auto& b = p.pts[(i + 1) % p.pts.size()];
    const double ex = b[0] - a[0], ey = b[1] - a[1];
    const double t = std::clamp(((x - a[0]) * ex + (y - a[1]) * ey) / (ex * ex + ey * ey), 0.0, 1.0);
    best = std::min(best, std::hypot(a[0] + t * ex - x, a[1] + t * ey - y));
  }
  return best;
}

std::vector<Polygon2> concave_polygons() {
  std::vector<Polygon2> out;
  out.push_back({"L", {{0, 0}, {2, 0}, {2, 0.5}, {0.5, 0.5}, {0.5, 2}, {0, 2}}});
  Polygon2 star{"star", {}};
  for (int i = 0; i < 10; ++i) {
    const double a = std::numbers::pi / 2 + i * std::numbers::pi / 5, r = (i % 2) ? 0.38 : 1.0;
    star.pts.push_back({r * std::cos(a), r * std::sin(a)});
  }
  out.push_back(star);
  // A comb with 20 teeth of width 1 and gaps of 1 on a spine 1 high.
  Polygon2 comb{"comb", {{0, 0}, {39, 0}}};
  for (int i = 19; i >= 1; --i) {
    comb.pts.push_back({2.0 * i + 1, 5});
    comb.pts.push_back({2.0 * i, 5});
    comb.pts.push_back({2.0 * i, 1});
    comb.pts.push_back({2.0 * i - 1, 1});
  }
  comb.pts.push_back({1, 5});
  comb.pts.push_back({0, 5});
  out.push_back(comb);
  // A gear outline: 36 teeth of 4 vertices each (144 vertices), root radius
  // 0.8, tip radius 1, as the SPD gears faces.
  Polygon2 gear{"gear", {}};
  for (int t = 0; t < 36; ++t) {
    const double a0 = 2 * std::numbers::pi * t / 36, w = 2 * std::numbers::pi / 36;
    const double angle[4] = {a0, a0 + 0.2 * w, a0 + 0.45 * w, a0 + 0.65 * w};
    const double radius[4] = {0.8, 1.0, 1.0, 0.8};
    for (int k = 0; k < 4; ++k) gear.pts.push_back({radius[k] * std::cos(angle[k]), radius[k] * std::sin(angle[k])});
  }
  out.push_back(gear);
  return out;
}

}  // namespace

TEST_CASE("grid: concave polygons (L, star, 20-tooth comb, 144-vertex gear) are triangulated exactly and hit only in their body") {
  // Each outline is placed, in both windings, on the tilted plane
  // origin + x ex + y ey. Its coefficients are exact in float, so outlines
  // with integer coordinates (L, comb) stay exactly planar and their
  // collinear vertices exactly collinear.
  const Vec3 ex{1, 0, 0.5f}, ey{0, 1, 0.25f};
  const Vec3 ez = normalize(cross(ex, ey));
  const double area_scale = length(cross(ex, ey));  // 3D area per unit of outline area
  const Vec3 origin{3, -2, 0.5f};
  for (const Polygon2& poly2 : concave_polygons()) {
    for (bool reversed : {false, true}) {
      CAPTURE(poly2.name);
      CAPTURE(reversed);
      Polygon2 p = poly2;
      if (reversed) std::reverse(p.pts.begin(), p.pts.end());
      std::vector<Vec3> v;
      for (const auto& q : p.pts) v.push_back(origin + ex * float(q[0]) + ey * float(q[1]));
      const std::uint32_t n = std::uint32_t(v.size());
      // Area and facing of the polygon (Newell normal), in double.
      auto cross_d = [](const Vec3& a, const Vec3& b, const Vec3& c) {
        const double u[3] = {double(b.x) - a.x, double(b.y) - a.y, double(b.z) - a.z};
        const double w[3] = {double(c.x) - a.x, double(c.y) - a.y, double(c.z) - a.z};
        return std::array<double, 3>{u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
      };
      auto norm_d = [](const std::array<double, 3>& a) { return std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); };
      std::array<double, 3> newell{0, 0, 0};
      for (std::uint32_t i = 1; i + 1 < n; ++i) {
        const auto c = cross_d(v[0], v[i], v[i + 1]);
        for (int a = 0; a < 3; ++a) newell[a] += c[a];
      }
      const double area = 0.5 * norm_d(newell);
      CHECK(area == doctest::Approx(std::fabs(shoelace(p)) * area_scale).epsilon(1e-5));

      std::vector<std::uint32_t> tris;
      triangulate_polygon(v.data(), n, tris);
      CHECK(tris.size() == 3 * (n - 2));
      double sum = 0;
      std::size_t flipped = 0;
      for (std::size_t t = 0; t < tris.size(); t += 3) {
        REQUIRE(tris[t] < n);
        REQUIRE(tris[t + 1] < n);
        REQUIRE(tris[t + 2] < n);
        const auto nt = cross_d(v[tris[t]], v[tris[t + 1]], v[tris[t + 2]]);
        flipped += !(nt[0] * newell[0] + nt[1] * newell[1] + nt[2] * newell[2] > 0.0);
        sum += 0.5 * norm_d(nt);
      }
      CHECK(flipped == 0);
      // Pieces that all face the same way and sum to the polygon's area
      // cover it exactly once.
      CHECK(sum == doctest::Approx(area).epsilon(1e-9));

      // Through the database and grid: rays into the notches miss, rays into
      // the body hit (points within 1e-3 of the outline are skipped).
      Scene s;
      s.add_polygon(v.data(), n);
      const Built b(s);
      CHECK(b.db.primitives.size() == tris.size() / 3);
      double lo[2] = {1e300, 1e300}, hi[2] = {-1e300, -1e300};
      for (const auto& q : p.pts)
        for (int a = 0; a < 2; ++a) {
          lo[a] = std::min(lo[a], q[a]);
          hi[a] = std::max(hi[a], q[a]);
        }
      const double size = std::max(hi[0] - lo[0], hi[1] - lo[1]);
      Rng rng(53);
      TraversalScratch scratch;
      Failures wrong;
      std::size_t in = 0, out = 0;
      for (int i = 0; i < 4000; ++i) {
        const double x = lo[0] + (hi[0] - lo[0]) * uniform(rng, 0, 1);
        const double y = lo[1] + (hi[1] - lo[1]) * uniform(rng, 0, 1);
        if (outline_distance(p, x, y) < 1e-3 * size) continue;
        const bool want = inside(p, x, y);
        const Vec3 target = origin + ex * float(x) + ey * float(y);
        const Vec3 o = target + ez * float(size) + ex * float(0.3 * size * uniform(rng, -1, 1));
        Hit h;
        const Ray ray{o, target - o, 0.0f, kInfinity};
        const bool got = intersect_closest(b.view(), ray, h, scratch);
        if (got != want) wrong.add(str(ray) + (want ? " missed the body" : " hit a notch"));
        (want ? in : out) += 1;
      }
      INFO("wrong rays:" << wrong.first);
      CHECK(in > 500);
      CHECK(out > 200);
      CHECK(wrong.count == 0);
    }
  }
}
