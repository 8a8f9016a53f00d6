// The one traversal: 3D-DDA through a uniform grid (Amanatides & Woo, "A
// Fast Voxel Traversal Algorithm for Ray Tracing", Eurographics 1987) with
// per-ray mailboxing, written against a *database view* so that sequential,
// replicated, svm and dataflow modes run the same code on the same values
// (DESIGN.md, "One tracer, several data views").
//
// A database view V provides (all const, owner thread only):
//   const GridInfo& grid_info() const;
//   template <class F> void for_each_in_cell(std::uint32_t cell, F&& f) const;
//       // calls f(std::uint32_t primitive_id) for each listed primitive
//   const Primitive& primitive(std::uint32_t id) const;
// DirectView (direct_view.h) is the plain-array one.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

#include "core/grid.h"
#include "core/intersect.h"
#include "core/math.h"

namespace raynode::core {

/// The nearest hit of a ray.
struct Hit {
  float t = kInfinity;                     ///< ray parameter of the hit
  std::uint32_t primitive = kNoPrimitive;  ///< index into the database's primitives
  float u = 0, v = 0;                      ///< triangle barycentrics (weights of v1, v2)
  bool found() const { return primitive != kNoPrimitive; }
};

/// Work counters of traversals (summed over the rays a scratch has served).
struct TraversalStats {
  std::uint64_t rays = 0;
  std::uint64_t cells_visited = 0;
  std::uint64_t triangle_tests = 0;
  std::uint64_t sphere_tests = 0;
  std::uint64_t cone_tests = 0;
  std::uint64_t mailbox_skips = 0;  ///< tests avoided because the primitive was already tested
  TraversalStats& operator+=(const TraversalStats& o) {
    rays += o.rays;
    cells_visited += o.cells_visited;
    triangle_tests += o.triangle_tests;
    sphere_tests += o.sphere_tests;
    cone_tests += o.cone_tests;
    mailbox_skips += o.mailbox_skips;
    return *this;
  }
};

/// Per-ray mailbox (hashed, after Wald's hashed mailboxing, 2004): a small
/// open-addressing set of the primitive ids already tested by the current
/// ray, stamped with a ray counter so that starting a ray costs O(1). Lives
/// in the thread's (or node's) scratch, never in the shared database, so it
/// is safe for shared-memory threads and paged databases alike. A ray that
/// tests more than kProbe-collision-chains' worth of primitives may retest
/// one (slower, never wrong).
class Mailbox {
 public:
  static constexpr std::uint32_t kSlots = 256;  // power of two
  static constexpr std::uint32_t kProbe = 8;

  Mailbox() { std::memset(slots_, 0, sizeof(slots_)); }

  /// Starts a new ray: forgets every id in O(1).
  void next_ray() {
    if (++stamp_ == 0) {
      std::memset(slots_, 0, sizeof(slots_));
      stamp_ = 1;
    }
  }
  /// Returns true if `id` was already tested by this ray; otherwise records it.
  bool seen_or_insert(std::uint32_t id) {
    const std::uint64_t key = (std::uint64_t(stamp_) << 32) | id;
    std::uint32_t h = (id * 0x9E3779B1u) >> 24;  // top 8 bits: kSlots = 256
    for (std::uint32_t i = 0; i < kProbe; ++i, h = (h + 1) & (kSlots - 1)) {
      const std::uint64_t s = slots_[h];
      if (s == key) return true;
      if ((s >> 32) != stamp_) {
        slots_[h] = key;
        return false;
      }
    }
    slots_[(id * 0x9E3779B1u) >> 24] = key;  // chain full: evict its head
    return false;
  }

 private:
  std::uint64_t slots_[kSlots];
  std::uint32_t stamp_ = 1;
};

/// Per-thread (per-node) mutable state of traversals.
struct TraversalScratch {
  Mailbox mailbox;
  TraversalStats stats;
};

/// Tests one primitive; on a hit closer than hit.t, updates `hit`.
[[gnu::always_inline]] inline bool intersect_primitive(const Primitive& p, std::uint32_t id, const Ray& ray, const WatertightRay& w,
                                Hit& hit, TraversalStats& stats) {
  switch (p.kind) {
    case PrimitiveKind::kTriangle: {
      ++stats.triangle_tests;
      TriangleHit th;
      if (intersect_triangle(ray, w, p.vertex(0), p.vertex(1), p.vertex(2), hit.t, th)) {
        hit.t = th.t;
        hit.u = th.u;
        hit.v = th.v;
        hit.primitive = id;
        return true;
      }
      return false;
    }
    case PrimitiveKind::kSphere: {
      ++stats.sphere_tests;
      float t;
      if (intersect_sphere(ray, p.center(), p.radius(), hit.t, t)) {
        hit = Hit{t, id, 0, 0};
        return true;
      }
      return false;
    }
    case PrimitiveKind::kCone: {
      ++stats.cone_tests;
      float t;
      if (intersect_cone(ray, p.cone_base(), p.cone_base_radius(), p.cone_apex(), p.cone_apex_radius(), hit.t,
                         t)) {
        hit = Hit{t, id, 0, 0};
        return true;
      }
      return false;
    }
  }
  return false;
}

/// Walks the grid cells pierced by `ray` in order, calling visit(cell, t_exit)
/// for each; stops when visit returns true. t_exit is the ray parameter where
/// the ray leaves the cell. Rays with zero direction components, and rays
/// starting inside, outside or on the boundary of the grid are handled.
/// Returns false if the ray misses the grid. Precondition: is_valid_ray(ray).
template <class Visit>
inline void walk_grid(const GridInfo& g, const Ray& ray, Visit&& visit) {
  const Vec3 inv{1.0f / ray.direction.x, 1.0f / ray.direction.y, 1.0f / ray.direction.z};
  float t0, t1;
  if (!intersect_bounds(g.bounds, ray, inv, t0, t1)) return;
  const Vec3 p = ray.at(t0);
  int cell[3], step[3], stop[3];
  float next_t[3];
  for (int a = 0; a < 3; ++a) {
    int c = static_cast<int>(std::floor((p[a] - g.bounds.lower[a]) * g.inv_cell_size[a]));
    c = c < 0 ? 0 : (c >= g.res[a] ? g.res[a] - 1 : c);
    cell[a] = c;
    const float d = ray.direction[a];
    if (d > 0.0f) {
      step[a] = 1;
      stop[a] = g.res[a];
      next_t[a] = (g.bounds.lower[a] + float(c + 1) * g.cell_size[a] - ray.origin[a]) * inv[a];
    } else if (d < 0.0f) {
      step[a] = -1;
      stop[a] = -1;
      next_t[a] = (g.bounds.lower[a] + float(c) * g.cell_size[a] - ray.origin[a]) * inv[a];
    } else {
      step[a] = 0;
      stop[a] = -2;
      next_t[a] = kInfinity;
    }
  }
  for (;;) {
    // Axis whose boundary comes first.
    const int axis = (next_t[0] < next_t[1]) ? (next_t[0] < next_t[2] ? 0 : 2) : (next_t[1] < next_t[2] ? 1 : 2);
    const float t_exit = next_t[axis] < t1 ? next_t[axis] : t1;
    if (visit(g.cell_index(cell[0], cell[1], cell[2]), t_exit)) return;
    if (next_t[axis] >= t1) return;
    cell[axis] += step[axis];
    if (cell[axis] == stop[axis]) return;
    const int boundary = step[axis] > 0 ? cell[axis] + 1 : cell[axis];
    next_t[axis] = (g.bounds.lower[axis] + float(boundary) * g.cell_size[axis] - ray.origin[axis]) * inv[axis];
  }
}

/// Nearest hit of `ray` in (ray.tmin, ray.tmax). Each primitive is tested at
/// most once per ray (mailbox); the walk stops as soon as the best hit lies
/// within the current cell. Returns hit.found(). Precondition:
/// is_valid_ray(ray) (callers reject NaN rays before).
template <class View>
inline bool intersect_closest(const View& view, const Ray& ray, Hit& hit, TraversalScratch& scratch) {
  hit = Hit{};
  hit.t = ray.tmax;
  const WatertightRay w(ray.direction);
  scratch.mailbox.next_ray();
  TraversalStats& stats = scratch.stats;
  ++stats.rays;
  bool found = false;
  walk_grid(view.grid_info(), ray, [&](std::uint32_t cell, float t_exit) {
    ++stats.cells_visited;
    view.for_each_in_cell(cell, [&](std::uint32_t id) {
      if (scratch.mailbox.seen_or_insert(id)) {
        ++stats.mailbox_skips;
        return;
      }
      found |= intersect_primitive(view.primitive(id), id, ray, w, hit, stats);
    });
    return found && hit.t <= t_exit;
  });
  if (!found) hit = Hit{};
  return found;
}

/// True if anything lies on `ray` in (ray.tmin, ray.tmax): the shadow-ray
/// query. Stops at the first hit found.
template <class View>
inline bool intersect_any(const View& view, const Ray& ray, TraversalScratch& scratch) {
  const WatertightRay w(ray.direction);
  scratch.mailbox.next_ray();
  TraversalStats& stats = scratch.stats;
  ++stats.rays;
  bool found = false;
  Hit hit;
  hit.t = ray.tmax;
  walk_grid(view.grid_info(), ray, [&](std::uint32_t cell, float) {
    ++stats.cells_visited;
    view.for_each_in_cell(cell, [&](std::uint32_t id) {
      if (found) return;
      if (scratch.mailbox.seen_or_insert(id)) {
        ++stats.mailbox_skips;
        return;
      }
      found = intersect_primitive(view.primitive(id), id, ray, w, hit, stats);
    });
    return found;
  });
  return found;
}

}  // namespace raynode::core
