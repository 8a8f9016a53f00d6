// Helpers shared by the grid test suites (grid_*_test.cpp): random scenes
// (random_scene.h), a brute-force closest hit over every primitive with the
// single-primitive tests (the grid must reproduce its t bit for bit), and a
// RayChecker that compares the grid with brute force and with Embree
// (embree_scene.h).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>
#include <string>

#include "core/cell_blocks.h"
#include "core/database.h"
#include "core/direct_view.h"
#include "core/embree_scene.h"
#include "core/grid.h"
#include "core/intersect.h"
#include "core/math.h"
#include "core/scene.h"
#include "core/traverse.h"
#include "core/validate.h"
#include "random_scene.h"

#include <doctest/doctest.h>

namespace raynode::testing::grid {

using namespace raynode::core;

// ---------------------------------------------------------------------------
// Helpers

inline std::string str(const Vec3& v) {
  char b[128];
  std::snprintf(b, sizeof b, "(%.9g, %.9g, %.9g)", v.x, v.y, v.z);
  return b;
}

inline std::string str(const Ray& r) {
  char b[64];
  std::snprintf(b, sizeof b, " tmin=%.9g tmax=%.9g", r.tmin, r.tmax);
  return "o=" + str(r.origin) + " d=" + str(r.direction) + b;
}

inline std::string str(const Hit& h) {
  if (!h.found()) return "miss";
  char b[64];
  std::snprintf(b, sizeof b, "prim %u t=%.9g", h.primitive, h.t);
  return b;
}

/// A validate report's example mismatches, one per line, for INFO.
inline std::string mismatch_lines(const ValidateReport& rep) {
  std::string lines;
  for (const MismatchExample& m : rep.examples)
    lines += "\n  " + m.set + " " + str(m.ray) + ": grid " + str(m.grid) + ", Embree " + str(m.embree);
  return lines;
}

inline Bounds3 grown(Bounds3 b, float fraction) {
  const Vec3 g = b.extent() * fraction;
  b.lower -= g;
  b.upper += g;
  return b;
}

// Database + grid, built in place (a DirectView points into both), and the
// grid's cells packed from one triangle on (cell_blocks.h).
struct Built {
  Database db;
  Grid grid;
  CellBlocks blocks;
  explicit Built(const Scene& s, const GridParams& gp = {}, const DatabaseParams& dp = {})
      : db(make_database(s, dp)), grid(build_grid(db, gp)), blocks(build_cell_blocks(db, grid, 1, PackKinds::kTrianglesAndSpheres)) {}
  /// Every cell walks its primitive list (the node modes' tracing).
  DirectView view() const { return DirectView(db, grid); }
  /// Every all-triangle cell tested in SIMD blocks (sequential mode's).
  DirectView packed_view() const { return DirectView(db, grid, &blocks); }
};

inline GridParams forced(int x, int y, int z) {
  GridParams p;
  p.resolution[0] = x;
  p.resolution[1] = y;
  p.resolution[2] = z;
  return p;
}

// Closest hit by testing every primitive with the single-primitive tests,
// the ray in the tracing frame `frame` (closest_in_frame), as the
// traversal tests it.
inline Hit brute_closest(const Database& db, const Ray& world_ray, float frame) {
  Hit out;
  closest_in_frame(frame, world_ray, out, [&](const Ray& ray, Hit& hit) {
  hit = Hit{};
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
  return hit.found();
  });
  return out;
}

// brute_closest in the frame of b's grid.
inline Hit brute_closest(const Built& b, const Ray& ray) {
  return brute_closest(b.db, ray, b.grid.info.frame_magnitude);
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
inline double ray_segment_distance(const Ray& r, const Vec3& a, const Vec3& b) {
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
inline bool decisive(const Database& db, const Ray& ray, float margin) {
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
    const Hit r = brute_closest(b, ray);
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

// A point inside the primitive (triangle centroid, sphere centre, cone axis
// midpoint): a ray aimed at it crosses the surface away from any edge.
inline Vec3 centre_of(const Primitive& p) {
  switch (p.kind) {
    case PrimitiveKind::kTriangle: return (p.vertex(0) + p.vertex(1) + p.vertex(2)) * (1.0f / 3.0f);
    case PrimitiveKind::kSphere: return p.center();
    case PrimitiveKind::kCone: return (p.cone_base() + p.cone_apex()) * 0.5f;
  }
  return {};
}

inline void add_quad(Scene& s, const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const Vec3 v[4] = {a, b, c, d};
  s.add_polygon(v, 4);
}

// Grid vertex coordinate i (0..res) on axis a, as GridInfo::cell_bounds gives it.
inline float grid_plane(const GridInfo& g, int a, int i) {
  return i == g.res[a] ? g.bounds.upper[a] : g.bounds.lower[a] + float(i) * g.cell_size[a];
}

// Rays along cell edges, from grid vertices, and inside cell planes.
inline void fire_grid_aligned_rays(RayChecker& chk, std::uint64_t seed) {
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
inline Scene scene_on_grid_planes(const int res[3]) {
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

}  // namespace raynode::testing::grid
