// Numerical stress of the grid and the triangle test through the whole
// traversal: closed meshes must not leak, scaled and moved scenes hit the
// same primitives, degenerate and collinear triangles never hit, and concave
// polygons (the SPD gears faces) are triangulated exactly.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
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
#include "core/scene.h"
#include "core/spd.h"
#include "core/traverse.h"
#include "grid_test_support.h"

namespace {
using namespace raynode::core;
using namespace raynode::testing::grid;
}  // namespace

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
        for (const bool packed : {false, true}) {
          const DirectView view = packed ? b.packed_view() : b.view();
          const std::string how = packed ? " (packed cells)" : "";
          Hit h;
          const bool hit = intersect_closest(view, ray, h, scratch);
          const bool any = intersect_any(view, ray, scratch);
          if (!hit || !any) {
            escaped.add(str(ray) + (hit ? " (any-hit missed)" : " escaped") + how);
          } else if (!(length(ray.at(h.t) - centre) <= radius * 1.0001f)) {
            escaped.add(str(ray) + ": hit outside the sphere at " + str(ray.at(h.t)) + how);
          }
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
          for (const bool packed : {false, true}) {
            const DirectView view = packed ? b.packed_view() : b.view();
            const std::string how = packed ? " (packed cells)" : "";
            Hit h;
            if (!intersect_closest(view, ray, h, scratch)) escaped.add(str(ray) + " escaped" + how);
            if (!intersect_any(view, ray, scratch)) escaped.add(str(ray) + " escaped the any-hit query" + how);
          }
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
  // Kept (drop_degenerate = false): the database holds them, and both grids
  // build without listing them (no ray can hit them, and the grid's walk does
  // not check its would-be hits for them).
  DatabaseParams keep;
  keep.drop_degenerate = false;
  const std::size_t degenerate = std::size(coincident) + std::size(collinear);
  for (const GridKind kind : {GridKind::kUniform, GridKind::kAdaptive}) {
    CAPTURE(grid_kind_name(kind));
    GridParams gp;
    gp.kind = kind;
    const Built b(s, gp, keep);
    REQUIRE(b.db.primitives.size() == good + degenerate);
    CHECK_FALSE(b.db.degenerate_triangles_dropped);
    REQUIRE(b.grid.cell_start.size() == b.grid.info.cell_count() + 1);
    CHECK(b.grid.cell_start.back() == b.grid.cell_primitives.size());
    std::vector<bool> listed(b.db.primitives.size(), false);
    for (std::uint32_t id : b.grid.cell_primitives) {
      REQUIRE(id < b.db.primitives.size());
      listed[id] = true;
    }
    CHECK(std::count(listed.begin(), listed.begin() + std::ptrdiff_t(good), true) == std::ptrdiff_t(good));
    CHECK(std::count(listed.begin() + std::ptrdiff_t(good), listed.end(), true) == 0);
    // Rays aimed at points of the coincident-vertex triangles, and along
    // their edges, never report them, through the lists and the packed cells.
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
          for (const DirectView& view : {b.view(), b.packed_view()}) {
            ++rays;
            Hit h;
            if (intersect_closest(view, r, h, scratch) && h.primitive >= good) bad.add(str(r) + ": " + str(h));
            if (!intersect_closest(view, r, h, scratch) && intersect_any(view, r, scratch))
              bad.add(str(r) + ": any-hit found what closest did not");
          }
        }
      }
    }
    INFO("rays hitting a degenerate triangle:" << bad.first);
    CHECK(rays >= 3000);
    CHECK(bad.count == 0);
  }
  // Dropped by default, and counted: then no ray can meet them.
  const Database dropped = make_database(s);
  CHECK(dropped.primitives.size() == good);
  CHECK(dropped.dropped_degenerate_triangles == degenerate);
  CHECK(dropped.degenerate_triangles_dropped);
}

// The collinear-triangle bug of intersect_triangle (intersect_test.cpp)
// through the database and grid, when make_database keeps degenerate
// triangles (DatabaseParams::drop_degenerate = false): before the fix a few
// hundred of these rays reported the collinear triangle.
TEST_CASE("grid: collinear triangles kept by drop_degenerate=false are never reported as hits") {
  Scene s;
  const Vec3 collinear[3] = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}};
  s.add_polygon(collinear, 3);
  const Vec3 anchor[3] = {{-1, -1, -1}, {-0.9f, -1, -1}, {-1, -0.9f, -1}};
  s.add_polygon(anchor, 3);
  DatabaseParams keep;
  keep.drop_degenerate = false;
  const Built b(s, {}, keep);
  REQUIRE(b.db.primitives.size() == 2);
  TraversalScratch scratch;
  Rng rng(2);
  std::uniform_real_distribution<float> u01(0, 1);
  std::normal_distribution<float> n01(0, 1);
  std::size_t hits = 0;
  for (int i = 0; i < 2000; ++i) {
    const Vec3 target = Vec3{2, 2, 2} * u01(rng);
    const Vec3 o = target + Vec3{n01(rng), n01(rng), n01(rng)} * 3.0f;
    Hit h;
    hits += intersect_closest(b.view(), Ray{o, target - o, 0, kInfinity}, h, scratch) && h.primitive == 0;
  }
  CHECK(hits == 0);
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
