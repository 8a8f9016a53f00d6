// The one traversal: 3D-DDA through a uniform grid (Amanatides & Woo, "A
// Fast Voxel Traversal Algorithm for Ray Tracing", Eurographics 1987) with
// per-ray mailboxing, written against a *database view* so that sequential,
// replicated, svm and dataflow modes run the same code on the same values
// (docs/architecture.md, "One tracer, several data views").
//
// A database view V provides (all const, owner thread only):
//   const GridInfo& grid_info() const;
//   template <class F> std::uint32_t for_each_in_cell(std::uint32_t cell, F&& f) const;
//       // calls f(std::uint32_t primitive_id) for each listed primitive and
//       // returns the cell's empty-space distance (Grid::empty_distance:
//       // 0 if it lists primitives; returning 1 for an empty cell is safe)
//   const Primitive& primitive(std::uint32_t id) const;
// and, for shading (shade.h), per-object data beside the primitives:
//   const Material& material(std::uint32_t id) const;
//   const TriangleNormals& vertex_normals(std::uint32_t id) const;
// A view whose cell directory is not in the linear cell order also offers
//   const CellKeyTables& cell_order() const;  // cell_order.h
// and then gets each cell by its key in that order (svm's bricked directory).
// A view of an adaptive grid (grid.h) offers either
//   SubGridTables sub_grid_tables() const;
// and then gets leaf cell ids (walk_cells), or, when its tables are not
// plain arrays (svm's paged view),
//   bool has_sub_grids() const;  SubGrid sub_grid(std::uint32_t i) const;
//   std::uint32_t top_large_leaf() const;  // the scene's large primitives' leaf, or kNoLeaf
// and then gets the ids the sub-grids' first_entry fields give. Either way
// its cell visit returns kSubGridCode + i for a top cell holding sub-grid i
// (grid.h, empty_leaf_code). The other views walk the uniform grid of
// grid_info() (the top grid).
// DirectView (direct_view.h) is the plain-array one. A reference a view
// returns may be valid only until the view's next call (svm's PagedView
// evicts pages): callers keep a copy of what they need across calls, and
// material() returns node-replicated data. for_each_in_cell must cope with
// f() calling primitive() (PagedView re-resolves its list page).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <concepts>
#include <type_traits>
#include <utility>

#include "core/cell_blocks.h"
#include "core/cell_order.h"
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
  std::uint64_t empty_jumps = 0;  ///< empty-space jumps tried (visited cells with distance >= kMinJumpDistance)
  std::uint64_t triangle_tests = 0;
  std::uint64_t sphere_tests = 0;
  std::uint64_t cone_tests = 0;
  std::uint64_t mailbox_skips = 0;  ///< tests avoided because the primitive was already tested
  TraversalStats& operator+=(const TraversalStats& o) {
    rays += o.rays;
    cells_visited += o.cells_visited;
    empty_jumps += o.empty_jumps;
    triangle_tests += o.triangle_tests;
    sphere_tests += o.sphere_tests;
    cone_tests += o.cone_tests;
    mailbox_skips += o.mailbox_skips;
    return *this;
  }
};

/// Per-ray mailbox (after Wald's hashed mailboxing, 2004): a direct-mapped
/// table of the primitive ids already tested by the current ray, indexed by
/// the id's low bits and stamped with a ray counter so that starting a ray
/// costs O(1). Lives in the thread's (or node's) scratch, never in the shared
/// database, so it is safe for shared-memory threads and paged databases
/// alike. Two ids of one ray that share a slot evict each other: the evicted
/// one may be tested again (slower, never wrong: a retest gives the same
/// answer and a hit only replaces a strictly farther one). Low bits, not a
/// hash: the primitives of a cell are mostly neighbours in the database
/// (one polygon's triangles, one mesh row), which then never collide.
class Mailbox {
 public:
  static constexpr std::uint32_t kSlots = 512;  // power of two

  Mailbox() { std::memset(slots_, 0, sizeof(slots_)); }

  /// Starts a new ray: forgets every id in O(1).
  void next_ray() {
    if (++stamp_ == 0) {
      std::memset(slots_, 0, sizeof(slots_));
      stamp_ = 1;
    }
  }
  /// Returns true if `id` was already tested by this ray; otherwise records it.
  bool seen_or_insert(std::uint32_t id) { return probe().seen_or_insert(id); }

  /// The current ray's view of the table: the stamp held in a register.
  /// Valid until the next next_ray().
  struct Probe {
    std::uint64_t* slots;
    std::uint64_t stamp;  ///< stamp << 32
    bool seen_or_insert(std::uint32_t id) {
      const std::uint64_t key = stamp | id;
      std::uint64_t& slot = slots[id & (kSlots - 1)];
      if (slot == key) return true;
      slot = key;
      return false;
    }
  };
  Probe probe() { return {slots_, std::uint64_t(stamp_) << 32}; }

 private:
  std::uint64_t slots_[kSlots];
  std::uint32_t stamp_ = 1;
};

/// Per-thread (per-node) mutable state of traversals.
struct TraversalScratch {
  Mailbox mailbox;
  TraversalStats stats;
};

namespace detail {

/// Sphere or cone test (not a triangle): the hit's t when one lies in
/// (ray.tmin, t_max), else +inf (a hit's t is below t_max, so never +inf).
/// Kept out of line so that the per-primitive loop, which inlines only the
/// triangle test, stays small; it takes and returns values, so that the
/// caller's hit and counters, to which it has no reference, stay in
/// registers.
[[gnu::noinline]] inline float intersect_curved(const Primitive& p, const Ray& ray, float t_max) {
  float t;
  if (p.kind == PrimitiveKind::kSphere) {
    if (!intersect_sphere(ray, p.center(), p.radius(), t_max, t)) return kInfinity;
  } else if (!intersect_cone(ray, p.cone_base(), p.cone_base_radius(), p.cone_apex(), p.cone_apex_radius(), t_max,
                             t)) {
    return kInfinity;
  }
  return t;
}

/// intersect_primitive with the triangle test's axis permutation fixed at
/// compile time (KX, KY, KZ as in intersect_triangle_axes), so that a whole
/// traversal dispatches on the permutation once per ray, and a hit taken
/// below `tmax` (hit.t, or tie_bound's). `kListed`: `p`
/// comes from a grid's lists, which hold no degenerate triangle
/// (build_grid), so a would-be hit is not checked for one.
template <int KX, int KY, int KZ, bool kListed = false>
[[gnu::always_inline]] inline bool intersect_primitive_axes(const Primitive& p, std::uint32_t id, const Ray& ray,
                                                            const WatertightRay& w, const TriangleRayLanes& lanes,
                                                            float tmax, Hit& hit, TraversalStats& stats) {
  if (p.kind != PrimitiveKind::kTriangle) [[unlikely]] {
    ++(p.kind == PrimitiveKind::kSphere ? stats.sphere_tests : stats.cone_tests);
    const float t = intersect_curved(p, ray, tmax);
    if (t == kInfinity) return false;  // a hit lies below t_max, never at +inf
    hit = Hit{t, id, 0, 0};
    return true;
  }
  ++stats.triangle_tests;
  TriangleHit th;
  if (!intersect_triangle_record_axes<KX, KY, KZ, !kListed>(ray, w, lanes, p.data, tmax, th)) return false;
  hit.t = th.t;
  hit.u = th.u;
  hit.v = th.v;
  hit.primitive = id;
  return true;
}

/// Calls f.template operator()<KX, KY, KZ>() for the ray's axis permutation
/// (WatertightRay::permutation): one run-time branch per ray.
template <class F>
[[gnu::always_inline]] inline decltype(auto) with_axes(const WatertightRay& w, F&& f) {
  switch (w.permutation) {
    case 0: return f.template operator()<1, 2, 0>();
    case 1: return f.template operator()<2, 1, 0>();
    case 2: return f.template operator()<2, 0, 1>();
    case 3: return f.template operator()<0, 2, 1>();
    case 4: return f.template operator()<0, 1, 2>();
    default: return f.template operator()<1, 0, 2>();
  }
}

}  // namespace detail

/// Tests one primitive; on a hit closer than hit.t, updates `hit`.
inline bool intersect_primitive(const Primitive& p, std::uint32_t id, const Ray& ray, const WatertightRay& w, Hit& hit,
                                TraversalStats& stats) {
  return detail::with_axes(w, [&]<int KX, int KY, int KZ>() {
    return detail::intersect_primitive_axes<KX, KY, KZ>(p, id, ray, w, TriangleRayLanes(ray, w), hit.t, hit, stats);
  });
}

/// What a walk's visit returns to stop the walk.
inline constexpr std::uint32_t kStopWalk = ~std::uint32_t(0);

/// The least empty-space distance the walk jumps from. A jump costs about
/// six cell steps (the model clock's fit: ~40 ns against 6.2 ns per cell)
/// and crosses at least d-1 cells, so shorter jumps do not pay;
/// `raynode bench accel` at 2, 3, 4, 6 and 8 put the best near 4 to 6, and
/// in svm, where each cell visit is also a page access, 4 is best.
inline constexpr std::uint32_t kMinJumpDistance = 4;

/// Walks the grid cells pierced by `ray` in order, calling
/// visit(cell, t_exit) for each; t_exit is the ray parameter where the ray
/// leaves the cell. visit returns kStopWalk to stop the walk, else the
/// cell's empty-space distance d (0 for a cell that lists primitives; see
/// Grid::empty_distance; 1 is always safe for an empty cell). Rays with
/// zero direction components, and rays starting inside, outside or on the
/// boundary of the grid are handled. Precondition: is_valid_ray(ray).
///
/// 3D-DDA (Amanatides & Woo 1987). The parameter of the next cell boundary
/// on each axis is recomputed from the boundary's grid index b, as
/// t = t_lower + b * t_cell (the ray's parameter at the grid's lower face
/// and per cell, both set once per walk), never accumulated (t += delta
/// drifts), so every view and every thread walks the
/// same cells for the same ray. Ties between axes go to the lowest of
/// (x < y ? (x < z ? x : z) : (y < z ? y : z)); the cell index is kept
/// linear (one add per step).
///
/// Empty-space jumps: when a visited cell reports d >= kMinJumpDistance,
/// the cube of cells within d-1 of it is empty, so the walk jumps to the ray's exit from that
/// cube (one boundary per axis, the nearest wins) and restarts the 3D-DDA
/// there, as at the grid's entry. The exit axis's cell is set by index, the
/// others by flooring the exit point, kept within the cube's span so that a
/// rounding error moves the restart by at most one cell, within the
/// cells' conservative margins (grid.h). A jump must pass the current
/// cell's exit and the previous jump's target, so the walk always ends.
///
/// The entry's slab test (intersect_bounds) and the entry's and the jumps'
/// per-axis arithmetic run in SSE lanes where SSE4.1 is available, each
/// lane in the scalar form's order, so that the cells are the same bit for
/// bit; the cell-by-cell steps stay scalar.
///
/// `order` numbers the cells handed to visit: LinearCellOrder (GridInfo::
/// cell_index, one add per step) or a CellKeyTables (a bricked directory's
/// keys, one table read per step; cell_order.h). The cells walked are the
/// same.
template <class Order, class Visit>
inline void walk_grid(const GridInfo& g, const Order& order, const Ray& ray, const Vec3& inv_v, Visit&& visit) {
  constexpr bool kLinear = std::is_same_v<Order, LinearCellOrder>;
  float t0, t1;  // the ray's stretch inside the grid's box
#if defined(__SSE4_1__)
  // The entry's and the jumps' per-axis arithmetic side by side in SSE
  // lanes (x, y, z, unused): each lane performs the scalar form's
  // operations in its order (no FMA: -ffp-contract=off), so the cells are
  // the same. Lane 3 is never read: four-float loads take the next member
  // there (GridInfo: bounds.upper.x after bounds.lower, res[0] after
  // bounds.upper, cell_size.x after res; Ray: direction.x after origin,
  // tmin after direction); the last member of each is set lane by lane.
  static_assert(offsetof(Bounds3, upper) == sizeof(Vec3) && offsetof(GridInfo, res) == sizeof(Bounds3) &&
                offsetof(GridInfo, cell_size) == offsetof(GridInfo, res) + 3 * sizeof(int) &&
                offsetof(Ray, tmin) == 2 * sizeof(Vec3));
  const __m128 v_lower = _mm_loadu_ps(&g.bounds.lower.x);
  const __m128 v_org = _mm_loadu_ps(&ray.origin.x);
  const __m128 v_dir = _mm_loadu_ps(&ray.direction.x);
  const __m128 v_inv = _mm_setr_ps(inv_v.x, inv_v.y, inv_v.z, 0.0f);
  const __m128i v_pos = _mm_castps_si128(_mm_cmpgt_ps(v_dir, _mm_setzero_ps()));  // -1 where step > 0
  const __m128i v_neg = _mm_castps_si128(_mm_cmplt_ps(v_dir, _mm_setzero_ps()));  // -1 where step < 0
  const __m128 v_still = _mm_castsi128_ps(_mm_cmpeq_epi32(_mm_or_si128(v_pos, v_neg), _mm_setzero_si128()));
  const __m128 v_inf = _mm_set1_ps(kInfinity);
  {
    // intersect_bounds, lane by lane: the slabs' entry and exit, sorted
    // (a NaN keeps the order, as the scalar swap does), the exit inflated;
    // a still axis misses when the origin lies outside its slab, and is
    // left out of t0 and t1 (+-inf), as a NaN lane is by the scalar
    // comparisons, which _mm_max_ss / _mm_min_ss repeat axis by axis.
    const __m128 v_upper = _mm_loadu_ps(&g.bounds.upper.x);
    const __m128 v_enter = _mm_mul_ps(_mm_sub_ps(v_lower, v_org), v_inv);
    const __m128 v_leave = _mm_mul_ps(_mm_sub_ps(v_upper, v_org), v_inv);
    const __m128 v_outside =
        _mm_and_ps(v_still, _mm_or_ps(_mm_cmplt_ps(v_org, v_lower), _mm_cmpgt_ps(v_org, v_upper)));
    if (_mm_movemask_ps(v_outside) & 7) return;
    const __m128 lo = _mm_blendv_ps(_mm_min_ps(v_leave, v_enter), _mm_set1_ps(-kInfinity), v_still);
    const __m128 grow = _mm_set1_ps(1.0f + 2.0f * 3.0f * std::numeric_limits<float>::epsilon());
    const __m128 hi = _mm_blendv_ps(_mm_mul_ps(_mm_max_ps(v_enter, v_leave), grow), v_inf, v_still);
    __m128 s0 = _mm_set_ss(ray.tmin), s1 = _mm_set_ss(ray.tmax);
    s0 = _mm_max_ss(lo, s0), s1 = _mm_min_ss(hi, s1);
    s0 = _mm_max_ss(_mm_shuffle_ps(lo, lo, 1), s0), s1 = _mm_min_ss(_mm_shuffle_ps(hi, hi, 1), s1);
    s0 = _mm_max_ss(_mm_shuffle_ps(lo, lo, 2), s0), s1 = _mm_min_ss(_mm_shuffle_ps(hi, hi, 2), s1);
    t0 = _mm_cvtss_f32(s0), t1 = _mm_cvtss_f32(s1);
    if (t0 > t1) return;
  }
#else
  if (!intersect_bounds(g.bounds, ray, inv_v, t0, t1)) return;
#endif
  const float org[3] = {ray.origin.x, ray.origin.y, ray.origin.z};
  const float dir[3] = {ray.direction.x, ray.direction.y, ray.direction.z};
  const float inv[3] = {inv_v.x, inv_v.y, inv_v.z};
  const float lower[3] = {g.bounds.lower.x, g.bounds.lower.y, g.bounds.lower.z};
  const float size[3] = {g.cell_size.x, g.cell_size.y, g.cell_size.z};
  const std::int32_t stride[3] = {1, g.res[0], g.res[0] * g.res[1]};
  // Boundary index b on axis a lies at the ray's parameter base[a] + b *
  // span[a], from the index each time (no sum carried from step to step).
  // Where either overflows (a direction component near 0, whose
  // reciprocal is huge or infinite: the ray crosses no boundary of that
  // axis before t ~ 1e37, far beyond the grid), the axis's boundaries lie
  // at +inf, as a still axis's.
  float base[3], span[3];
  for (int a = 0; a < 3; ++a) {
    base[a] = (lower[a] - org[a]) * inv[a];
    span[a] = size[a] * inv[a];
    if (!(std::fabs(base[a]) < kInfinity && std::fabs(span[a]) < kInfinity)) base[a] = kInfinity, span[a] = 0.0f;
  }
  int step[3];                   // +-1/0 per axis
  std::int32_t delta[3];         // linear index change per step
  const std::int32_t* steps[3];  // bricked: the key's change per step, by next boundary
  for (int a = 0; a < 3; ++a) {
    // Branch-free on the direction's sign (select, not jump).
    const bool pos_dir = dir[a] > 0.0f, neg_dir = dir[a] < 0.0f;
    step[a] = int(pos_dir) - int(neg_dir);
    delta[a] = step[a] * stride[a];
    if constexpr (!kLinear) steps[a] = pos_dir ? order.up[a] : order.down[a];
  }
  // Axis a's part of cell c's number.
  auto axis_key = [&](int a, int c) -> std::int32_t {
    if constexpr (kLinear) return c * stride[a];
    else return order.key[a][c];
  };
  // The walk keeps each axis's state in its own scalars (registers), not in
  // arrays indexed by the run-time axis: the next boundary's parameter n,
  // the steps left before leaving the grid l (-1 on a still axis: never
  // reached, n stays +inf) and the next boundary's index b.
  float n0, n1, n2;
  int l0, l1, l2, b0, b1, b2;
  std::int32_t cell;
#if defined(__SSE4_1__)
  const __m128 v_inv_size = _mm_setr_ps(g.inv_cell_size.x, g.inv_cell_size.y, g.inv_cell_size.z, 0.0f);
  const __m128i v_last =  // last cell per axis
      _mm_sub_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(g.res)), _mm_set1_epi32(1));
  const __m128 v_last_f = _mm_cvtepi32_ps(v_last);
  const __m128i v_step = _mm_sub_epi32(v_neg, v_pos);
  // clamped_floor((q - lower) / cell size) per lane.
  auto cells_of = [&](__m128 q) [[gnu::always_inline]] {
    const __m128 f = _mm_floor_ps(_mm_mul_ps(_mm_sub_ps(q, v_lower), v_inv_size));
    const __m128i c = _mm_cvttps_epi32(_mm_max_ps(f, _mm_setzero_ps()));  // NaN: max gives 0
    return _mm_blendv_epi8(c, v_last, _mm_castps_si128(_mm_cmpge_ps(f, v_last_f)));
  };
  // The ray's parameter at boundary index b per lane (+inf on a still axis).
  const __m128 v_base = _mm_setr_ps(base[0], base[1], base[2], 0.0f);
  const __m128 v_span = _mm_setr_ps(span[0], span[1], span[2], 0.0f);
  auto boundary_t = [&](__m128i b) [[gnu::always_inline]] {
    const __m128 t = _mm_add_ps(v_base, _mm_mul_ps(_mm_cvtepi32_ps(b), v_span));
    return _mm_blendv_ps(t, v_inf, v_still);
  };
  // The walk's state in cell c (per lane).
  auto start_in = [&](__m128i c) [[gnu::always_inline]] {
    const __m128i b = _mm_sub_epi32(c, v_pos);  // c + 1 where step > 0
    const __m128i left =
        _mm_blendv_epi8(_mm_blendv_epi8(_mm_set1_epi32(-1), c, v_neg), _mm_sub_epi32(v_last, c), v_pos);
    alignas(16) float n[4];
    alignas(16) std::int32_t ci[4], bi[4], li[4];
    _mm_store_ps(n, boundary_t(b));
    _mm_store_si128(reinterpret_cast<__m128i*>(ci), c);
    _mm_store_si128(reinterpret_cast<__m128i*>(bi), b);
    _mm_store_si128(reinterpret_cast<__m128i*>(li), left);
    n0 = n[0], n1 = n[1], n2 = n[2];
    b0 = bi[0], b1 = bi[1], b2 = bi[2];
    l0 = li[0], l1 = li[1], l2 = li[2];
    cell = axis_key(0, ci[0]) + axis_key(1, ci[1]) + axis_key(2, ci[2]);
  };
  start_in(cells_of(_mm_add_ps(v_org, _mm_mul_ps(v_dir, _mm_set1_ps(t0)))));
#else
  auto start_in = [&](const int c[3]) {
    int b[3], left[3];
    float next_t[3];
    for (int a = 0; a < 3; ++a) {
      b[a] = c[a] + int(step[a] > 0);
      next_t[a] = step[a] != 0 ? base[a] + float(b[a]) * span[a] : kInfinity;
      left[a] = step[a] > 0 ? g.res[a] - 1 - c[a] : (step[a] < 0 ? c[a] : -1);
    }
    n0 = next_t[0], n1 = next_t[1], n2 = next_t[2];
    b0 = b[0], b1 = b[1], b2 = b[2];
    l0 = left[0], l1 = left[1], l2 = left[2];
    cell = axis_key(0, c[0]) + axis_key(1, c[1]) + axis_key(2, c[2]);
  };
  {
    const Vec3 p = ray.at(t0);
    const float pos[3] = {p.x, p.y, p.z};
    const float inv_size[3] = {g.inv_cell_size.x, g.inv_cell_size.y, g.inv_cell_size.z};
    int c[3];
    for (int a = 0; a < 3; ++a) c[a] = clamped_floor((pos[a] - lower[a]) * inv_size[a], g.res[a]);
    start_in(c);
  }
#endif
  float t_jumped = -kInfinity;  // the last jump's target
  // One cell along axis a; false when the ray leaves the grid there.
  auto advance = [&](int& l, int& b, float& n, int a) [[gnu::always_inline]] {
    if (l == 0) return false;
    --l;
    if constexpr (kLinear) cell += delta[a];
    else cell += steps[a][b];  // b: the boundary crossed
    b += step[a];
    n = base[a] + float(b) * span[a];
    return true;
  };
  for (;;) {
    std::uint32_t d;
    float t_here;  // the current cell's exit
    int k;         // its axis
    // Axis of the first boundary: (n0 < n1) ? (n0 < n2 ? 0 : 2) : (n1 < n2 ? 1 : 2).
    if (n0 < n1 && n0 < n2) {
      d = visit(std::uint32_t(cell), n0 < t1 ? n0 : t1);
      if (d == kStopWalk || n0 >= t1) return;
      if (d < kMinJumpDistance) [[likely]] {
        if (!advance(l0, b0, n0, 0)) return;
        continue;
      }
      t_here = n0, k = 0;
    } else if (!(n0 < n1) && n1 < n2) {
      d = visit(std::uint32_t(cell), n1 < t1 ? n1 : t1);
      if (d == kStopWalk || n1 >= t1) return;
      if (d < kMinJumpDistance) [[likely]] {
        if (!advance(l1, b1, n1, 1)) return;
        continue;
      }
      t_here = n1, k = 1;
    } else {
      d = visit(std::uint32_t(cell), n2 < t1 ? n2 : t1);
      if (d == kStopWalk || n2 >= t1) return;
      if (d < kMinJumpDistance) [[likely]] {
        if (!advance(l2, b2, n2, 2)) return;
        continue;
      }
      t_here = n2, k = 2;
    }
    // An empty cube of radius r = d-1 around the current cell: its far
    // boundary on each moving axis (clamped to the grid) and the ray's
    // parameter there. The ray leaves the cube at the nearest, axis e.
    const int r = int(d) - 1;
#if defined(__SSE4_1__)
    const __m128i v_b = _mm_setr_epi32(b0, b1, b2, 0);
    // far = b + step * min(r, l); l < 0 on a still axis, whose t_far is +inf.
    const __m128i v_reach = _mm_min_epi32(_mm_set1_epi32(r), _mm_setr_epi32(l0, l1, l2, 0));
    const __m128i v_far = _mm_add_epi32(v_b, _mm_sign_epi32(v_reach, v_step));
    alignas(16) float t_far[4];
    alignas(16) std::int32_t far[4];
    _mm_store_ps(t_far, boundary_t(v_far));
    _mm_store_si128(reinterpret_cast<__m128i*>(far), v_far);
    const int e = (t_far[0] < t_far[1]) ? (t_far[0] < t_far[2] ? 0 : 2) : (t_far[1] < t_far[2] ? 1 : 2);
    const float t_jump = t_far[e];
    const int l_e = e == 0 ? l0 : (e == 1 ? l1 : l2);
#else
    const int b[3] = {b0, b1, b2}, l[3] = {l0, l1, l2};
    int far[3];
    float t_far[3];
    for (int a = 0; a < 3; ++a) {
      const int reach = r < l[a] ? r : l[a];  // l[a] < 0 on a still axis: t_far stays +inf
      far[a] = b[a] + step[a] * reach;
      t_far[a] = step[a] != 0 ? base[a] + float(far[a]) * span[a] : kInfinity;
    }
    const int e = (t_far[0] < t_far[1]) ? (t_far[0] < t_far[2] ? 0 : 2) : (t_far[1] < t_far[2] ? 1 : 2);
    const float t_jump = t_far[e];
    const int l_e = l[e];
#endif
    if (t_jump > t_here && t_jump > t_jumped) {
      // The ray leaves the grid, or its segment ends, inside the empty cube.
      if (t_jump >= t1 || r >= l_e) return;
      t_jumped = t_jump;
      // Restart in the cell just across the exit face on axis e; on the
      // other moving axes, the cell holding the exit point, kept within the
      // cube's span [current cell, far face's cell] and the grid; a still
      // axis keeps its cell.
#if defined(__SSE4_1__)
      const __m128i v_cur = _mm_add_epi32(v_b, v_pos);  // current cell: b - 1 where step > 0
      const __m128i v_lo = _mm_blendv_epi8(_mm_sub_epi32(v_far, _mm_set1_epi32(1)), v_cur, v_pos);
      const __m128i v_hi = _mm_blendv_epi8(v_cur, v_far, v_pos);
      const __m128i v_f = cells_of(_mm_add_ps(v_org, _mm_mul_ps(v_dir, _mm_set1_ps(t_jump))));
      const __m128i v_in = _mm_max_epi32(_mm_min_epi32(_mm_max_epi32(_mm_min_epi32(v_f, v_hi), v_lo), v_last),
                                         _mm_setzero_si128());
      const __m128i v_across = _mm_add_epi32(v_far, v_neg);  // far - 1 where step < 0
      __m128i v_c = _mm_blendv_epi8(v_in, v_cur, _mm_castps_si128(v_still));
      v_c = _mm_blendv_epi8(v_c, v_across, _mm_cmpeq_epi32(_mm_setr_epi32(0, 1, 2, 3), _mm_set1_epi32(e)));
      start_in(v_c);
#else
      const Vec3 q = ray.at(t_jump);
      const float qa[3] = {q.x, q.y, q.z};
      const float inv_size[3] = {g.inv_cell_size.x, g.inv_cell_size.y, g.inv_cell_size.z};
      int c[3];
      for (int a = 0; a < 3; ++a) {
        c[a] = b[a] - int(step[a] > 0);  // current cell on a still axis
        if (a == e) {
          c[a] = far[a] - int(step[a] < 0);  // just across the exit face
        } else if (step[a] != 0) {
          const int lo = step[a] > 0 ? c[a] : far[a] - 1, hi = step[a] > 0 ? far[a] : c[a];
          const int f = clamped_floor((qa[a] - lower[a]) * inv_size[a], g.res[a]);
          c[a] = f < lo ? lo : (f > hi ? hi : f);
          c[a] = c[a] > g.res[a] - 1 ? g.res[a] - 1 : (c[a] < 0 ? 0 : c[a]);
        }
      }
      start_in(c);
#endif
      continue;
    }
    // No gain: an ordinary step along k.
    if (!(k == 0 ? advance(l0, b0, n0, 0) : k == 1 ? advance(l1, b1, n1, 1) : advance(l2, b2, n2, 2))) return;
  }
}

/// walk_grid with the ray's reciprocal direction computed here.
template <class Order, class Visit>
inline void walk_grid(const GridInfo& g, const Order& order, const Ray& ray, Visit&& visit) {
  const Vec3 inv_v{1.0f / ray.direction.x, 1.0f / ray.direction.y, 1.0f / ray.direction.z};
  walk_grid(g, order, ray, inv_v, std::forward<Visit>(visit));
}

/// walk_grid in the linear cell order.
template <class Visit>
inline void walk_grid(const GridInfo& g, const Ray& ray, Visit&& visit) {
  walk_grid(g, LinearCellOrder{}, ray, std::forward<Visit>(visit));
}

/// Views whose cell directory is bricked offer cell_order() (a
/// CellKeyTables); the walk then hands them bricked keys.
template <class View>
concept has_cell_order = requires(const View& v) {
  { v.cell_order() } -> std::convertible_to<const CellKeyTables&>;
};
/// The cell order a view's walk uses.
template <class View>
decltype(auto) cell_order_of(const View& view) {
  if constexpr (has_cell_order<View>) return (view.cell_order());
  else return LinearCellOrder{};
}

/// Views with packed cells (cell_blocks.h) offer visit_cell(cell, f,
/// packed); the others are walked with for_each_in_cell.
template <class View>
concept has_packed_cells = requires(const View& v, std::uint32_t c) {
  v.visit_cell(c, [](std::uint32_t) {}, [](const CellBlockSpan&) {});
};

/// Views over an adaptive grid offer sub_grid_tables() (a SubGridTables,
/// grid.h; empty spans for a uniform grid), and their cell visit returns
/// kSubGridCode + i for a top cell holding sub-grid i.
template <class View>
concept has_sub_grids = requires(const View& v) {
  { v.sub_grid_tables() } -> std::convertible_to<SubGridTables>;
};

/// Views over an adaptive grid whose sub-grid records and cell entries
/// are read through the view (svm's PagedView): sub_grid(i) returns a copy
/// of sub-grid i's record, whose first_entry is the id the view's cell
/// visit takes for the sub-grid's cell 0 (its cells follow in linear
/// order), a cell visit returns kSubGridCode + i for a cell holding
/// sub-grid i, and top_large_leaf() is the id of the leaf listing the
/// scene's large primitives beside the top grid (kNoLeaf if none).
template <class View>
concept has_paged_sub_grids = requires(const View& v, std::uint32_t i) {
  { v.has_sub_grids() } -> std::convertible_to<bool>;
  { v.sub_grid(i) } -> std::convertible_to<SubGrid>;
  { v.top_large_leaf() } -> std::convertible_to<std::uint32_t>;
};

namespace detail {

/// What a walk below one grid of an adaptive hierarchy hands back: the
/// visitor, with its state as the walk left it, and whether visit stopped
/// the walk.
template <class Visit>
struct SubWalk {
  Visit visit;
  bool stopped;
};

/// Sub-grid i's record: a reference into the view's table, or the copy a
/// paged view reads.
template <class View>
decltype(auto) sub_grid_of(const View& view, std::uint32_t i) {
  if constexpr (has_sub_grids<View>) return (view.sub_grid_tables().sub_grids[i]);
  else return view.sub_grid(i);
}

/// walk_cells below one grid of an adaptive hierarchy: walk_grid over
/// sub-grid `index`, whose cell c is leaf first_entry + c; a visit's
/// kSubGridCode + j for a cell descends into sub-grid j, recursively (its
/// bounds hold every point of the cell that the primitives it lists reach,
/// so the inner walk covers the ray's piece that can hit them). The cell's
/// large primitives, if any, are visited first. The visitor comes in and
/// goes back by value (see walk_cells).
template <class View, class Visit>
[[gnu::noinline]] SubWalk<Visit> walk_sub_grid(const View& view, std::uint32_t index, const Ray& ray,
                                               const Vec3& inv_v, Visit visit) {
  const auto& g = sub_grid_of(view, index);  // a paged view's copy lives as long as g
  bool stopped = false;
  // The cell's large primitives first (SubGrid): a hit there ends no walk
  // but a shadow ray's, as the sub-grid's cells may hold nearer ones.
  if (g.large_list && visit(g.first_entry + g.info.cell_count(), -kInfinity) == kStopWalk) return {visit, true};
  walk_grid(g.info, LinearCellOrder{}, ray, inv_v, [&](std::uint32_t cell, float t_exit) -> std::uint32_t {
    const std::uint32_t d = visit(g.first_entry + cell, t_exit);
    if (d < kSubGridCode) [[likely]]
      return d;
    if (d == kStopWalk) {
      stopped = true;
      return kStopWalk;
    }
    SubWalk<Visit> below = walk_sub_grid(view, d - kSubGridCode, ray, inv_v, visit);
    visit = below.visit;
    stopped = below.stopped;
    return stopped ? kStopWalk : 0;
  });
  return {visit, stopped};
}

/// The leaf listing the scene's large primitives beside the top grid, or
/// kNoLeaf.
template <class View>
std::uint32_t top_large_leaf(const View& view) {
  if constexpr (has_sub_grids<View>) return view.sub_grid_tables().top_large_leaf();
  else return view.top_large_leaf();
}

/// True when `view` is over an adaptive grid that holds sub-grids.
template <class View>
bool holds_sub_grids(const View& view) {
  if constexpr (has_sub_grids<View>) return !view.sub_grid_tables().sub_grids.empty();
  else if constexpr (has_paged_sub_grids<View>) return view.has_sub_grids();
  else return false;
}

}  // namespace detail

/// Walks the leaf cells pierced by `ray` in order, calling visit(leaf,
/// t_exit) as walk_grid does: over the view's uniform grid, or, for a view
/// of an adaptive grid (has_sub_grids or has_paged_sub_grids, with
/// sub-grids), by a nested walk — walk_grid over the top grid and, in each
/// cell holding a sub-grid, walk_grid over that sub-grid (recursively),
/// each with the 3D-DDA's determinism and empty-space jumps. A leaf's
/// t_exit is its own exit, so the closest-hit early exit keeps its meaning;
/// visit's kStopWalk ends every level. The mailbox dedups primitives listed
/// at several levels.
///
/// `visit` is a copyable object (not a lambda: it is assigned to): a walk
/// below the top grid, which is out of line, takes a copy and hands it
/// back, which is assigned to `visit`. So the visitor's address never
/// leaves the caller, and its state (the hit, counters, mailbox stamp)
/// stays in registers through the top grid's walk; a reference handed to
/// the out-of-line walk would keep it in memory for the whole walk.
template <class View, class Visit>
inline void walk_cells(const View& view, const Ray& ray, Visit& visit) {
  if constexpr (has_sub_grids<View> || has_paged_sub_grids<View>) {
    if (detail::holds_sub_grids(view)) {
      // The scene's large primitives first, as a sub-grid's (walk_sub_grid).
      if (const std::uint32_t large = detail::top_large_leaf(view); large != kNoLeaf) [[unlikely]]
        if (view.grid_info().large_slab.may_meet(ray) && visit(large, -kInfinity) == kStopWalk) return;
      // The top grid's walk is inlined here, so that its leaves are visited
      // with the caller's hit and counters in registers; only a cell holding
      // a sub-grid (its visit returns kSubGridCode + i) calls out. Its
      // cells in the view's order (linear or bricked keys); cell c is leaf c.
      const Vec3 inv_v{1.0f / ray.direction.x, 1.0f / ray.direction.y, 1.0f / ray.direction.z};
      walk_grid(view.grid_info(), cell_order_of(view), ray, inv_v, [&](std::uint32_t cell, float t_exit) -> std::uint32_t {
        const std::uint32_t d = visit(cell, t_exit);
        if (d < kSubGridCode || d == kStopWalk) [[likely]]
          return d;
        const detail::SubWalk<Visit> below = detail::walk_sub_grid(view, d - kSubGridCode, ray, inv_v, visit);
        visit = below.visit;
        return below.stopped ? kStopWalk : 0;
      });
      return;
    }
  }
  walk_grid(view.grid_info(), cell_order_of(view), ray, visit);
}

/// True when `ray` is tested whole in the frame of magnitude `frame`
/// because its origin lies inside the frame's cube (framed_ray's fast path).
inline bool origin_in_frame(float frame, const Ray& ray) { return max_component(abs(ray.origin)) <= frame; }

/// The tracing frame (TopGridInfo::frame_magnitude `frame`): a ray whose
/// origin lies outside the cube [-frame, frame]^3 and whose line (t >= 0)
/// enters it is tested in two pieces: up to the entry from its own origin,
/// and from the entry on from the entry point, computed in double and
/// rounded once (the other piece's tmin and tmax moved by the entry's
/// parameter, a hit's t moved back). A far origin's rounding (a point of a
/// floor 1000x the objects' size, a distant eye) then never reaches the
/// objects' walk and tests, whose rounding the cells' margins hold
/// (grid.h), while what lies near the origin (the surface a secondary ray
/// leaves) is still tested from the origin, as its spawn offset assumes.
/// The split depends on the ray's line alone, not on tmin or tmax, so a ray
/// traced in pieces (dataflow's regions) is split alike.
///
/// Returns the entry's parameter s, with `framed` the piece from it (tmin
/// at most 0: from 2^-20 s before the entry, so the pieces overlap), or 0
/// with `framed` = `ray` when the ray is tested whole.
[[gnu::noinline]] inline double framed_ray(float frame, const Ray& ray, Ray& framed) {
  framed = ray;
  if (origin_in_frame(frame, ray) || !(frame > 0.0f)) return 0.0;
  double t0 = -std::numeric_limits<double>::infinity(), t1 = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    const double o = ray.origin[a], d = ray.direction[a];
    if (d == 0.0) {
      if (std::fabs(o) > frame) return 0.0;
      continue;
    }
    double lo = (-double(frame) - o) / d, hi = (double(frame) - o) / d;
    if (lo > hi) std::swap(lo, hi);
    t0 = std::max(t0, lo);
    t1 = std::min(t1, hi);
  }
  if (!(t0 <= t1) || !(t0 > 0.0)) return 0.0;
  for (int a = 0; a < 3; ++a) framed.origin[a] = float(double(ray.origin[a]) + double(ray.direction[a]) * t0);
  framed.tmin = float(std::max(double(ray.tmin) - t0, -0x1p-20 * t0));
  framed.tmax = float(double(ray.tmax) - t0);  // +inf stays +inf
  return t0;
}

/// The piece of `ray` before the frame entry at parameter s (framed_ray):
/// up to 2^-20 s past s, as the framed piece starts 2^-20 s before it. A
/// surface the ray crosses at the entry is found by one piece or the
/// other: this one, tested from the far origin, with a float t that may err
/// past s; the framed one, whose origin is a point of the line and not a
/// surface, refuses no hit near it (WatertightRay, tmin < 0) and takes
/// the t of one there in double.
inline Ray before_frame(const Ray& ray, double s) {
  Ray before = ray;
  before.tmax = std::min(ray.tmax, std::nextafter(float(s * (1.0 + 0x1p-20)), kInfinity));
  return before;
}

/// The closest hit of `ray` in the tracing frame `frame` (framed_ray):
/// closest(const Ray& piece, Hit& hit) -> bool (the nearest hit of a
/// piece, its t in that piece's parameter) for the whole ray, or for the
/// piece before the frame and, unless that piece's hit lies clearly before
/// the entry, the piece in it; the nearer hit wins, an exact tie going to
/// the lower primitive id.
template <class Closest>
bool closest_in_frame(float frame, const Ray& ray, Hit& hit, Closest&& closest) {
  if (origin_in_frame(frame, ray)) [[likely]]
    return closest(ray, hit);
  Ray framed;
  const double s = framed_ray(frame, ray, framed);
  if (s == 0.0) return closest(ray, hit);
  const Ray before = before_frame(ray, s);
  Hit near;
  const bool found_near = before.tmin <= before.tmax && closest(before, near);
  if (found_near && double(near.t) < s * (1.0 - 0x1p-20)) {
    hit = near;
    return true;
  }
  Hit far;
  const bool found_far = framed.tmin <= framed.tmax && closest(framed, far);
  if (found_far) far.t = float(s + double(far.t));
  if (!found_far && !found_near) {
    hit = Hit{};
    return false;
  }
  hit = !found_far || (found_near && (near.t < far.t || (near.t == far.t && near.primitive < far.primitive))) ? near
                                                                                                           : far;
  return true;
}

/// intersect_any's answer in the tracing frame: any(const Ray& piece) ->
/// bool for the whole ray, or for the piece before the frame, then the
/// piece in it (closest_in_frame).
template <class Any>
bool any_in_frame(float frame, const Ray& ray, Any&& any) {
  if (origin_in_frame(frame, ray)) [[likely]]
    return any(ray);
  Ray framed;
  const double s = framed_ray(frame, ray, framed);
  if (s == 0.0) return any(ray);
  const Ray before = before_frame(ray, s);
  if (before.tmin <= before.tmax && any(before)) return true;
  return framed.tmin <= framed.tmax && any(framed);
}

namespace detail {

// The visitors below keep the hit, the counters and the mailbox's stamp in
// their own members, which the compiler keeps in registers (walk_cells
// never takes their address; they are written back once per ray): a store
// through `scratch` could alias them and would force a reload per primitive.

/// The cell visit of both queries: tests a leaf's primitives and keeps the
/// nearest hit. intersect_closest (kAny false) stops the walk once that hit
/// lies within the leaf; intersect_any (kAny true) at the first hit.
template <int KX, int KY, int KZ, class View, bool kAny>
struct CellVisit {
  const View* view;
  const Ray* ray;
  const WatertightRay* w;
  const TriangleRayLanes* lanes;
  Mailbox::Probe mailbox;
  Hit hit;
  /// The triangle the ray leaves, or kNoPrimitive: never tested (see
  /// intersect_closest).
  std::uint32_t origin_triangle = kNoPrimitive;
  bool found = false;
  TraversalStats stats{};

  [[gnu::always_inline]] std::uint32_t operator()(std::uint32_t cell, float t_exit) {
    ++stats.cells_visited;
    const auto listed = [&](std::uint32_t id) [[gnu::always_inline]] {
      if (kAny && found) return;
      if (id == origin_triangle) return;
      if (mailbox.seen_or_insert(id)) {
        ++stats.mailbox_skips;
        return;
      }
      const float tmax = kAny ? hit.t : tie_bound(hit.t, hit.primitive, id);
      found |= intersect_primitive_axes<KX, KY, KZ, true>(view->primitive(id), id, *ray, *w, *lanes, tmax, hit, stats);
    };
    std::uint32_t empty;
    if constexpr (has_packed_cells<View>) {
      empty = view->visit_cell(cell, listed, [&]<class Span>(const Span& cb) [[gnu::always_inline]] {
        // (any: a paged view hands a cell over in pieces, and one hit is enough)
        if (kAny && found) return;
        if constexpr (std::is_same_v<Span, SphereBlockSpan>)
          found |= intersect_cell_spheres<kAny>(cb, *ray, mailbox, hit.t, hit.u, hit.v, hit.primitive,
                                                stats.sphere_tests, stats.mailbox_skips);
        else
          found |= intersect_cell_blocks<KX, KY, KZ, kAny>(cb, *ray, *w, origin_triangle, hit.t, hit.u, hit.v,
                                                          hit.primitive, stats.triangle_tests);
      });
    } else {
      empty = view->for_each_in_cell(cell, listed);
    }
    if (empty != 0) {
      if constexpr (has_sub_grids<View> || has_paged_sub_grids<View>) {
        if (empty >= kSubGridCode) [[unlikely]] {
          --stats.cells_visited;  // a cell holding a sub-grid: its leaves are counted
          return empty;
        }
      }
      // A closest hit may lie in an empty leaf: one found in a sub-grid's
      // large-primitive leaf lies in its cells, which do not list it. (An
      // any-hit walk has stopped at its hit.)
      if (!kAny && found && hit.t <= t_exit) return kStopWalk;
      stats.empty_jumps += empty >= kMinJumpDistance;
      return empty;
    }
    return found && (kAny || hit.t <= t_exit) ? kStopWalk : 0;
  }
};

template <int KX, int KY, int KZ, class View>
[[gnu::flatten]] inline bool intersect_closest_axes(const View& view, const Ray& ray, const WatertightRay& w, Hit& hit_out,
                                   TraversalScratch& scratch, std::uint32_t origin_triangle) {
  const TriangleRayLanes lanes(ray, w);
  CellVisit<KX, KY, KZ, View, false> visit{&view, &ray, &w, &lanes, scratch.mailbox.probe(), hit_out, origin_triangle};
  visit.hit.primitive = 0;  // no hit yet: no id is below it (tie_bound)
  walk_cells(view, ray, visit);
  scratch.stats += visit.stats;
  hit_out = visit.hit;
  return visit.found;
}

template <int KX, int KY, int KZ, class View>
[[gnu::flatten]] inline bool intersect_any_axes(const View& view, const Ray& ray, const WatertightRay& w, TraversalScratch& scratch,
                                               std::uint32_t origin_triangle) {
  const TriangleRayLanes lanes(ray, w);
  Hit hit;
  hit.t = ray.tmax;
  CellVisit<KX, KY, KZ, View, true> visit{&view, &ray, &w, &lanes, scratch.mailbox.probe(), hit, origin_triangle};
  walk_cells(view, ray, visit);
  scratch.stats += visit.stats;
  return visit.found;
}

}  // namespace detail

namespace detail {

/// intersect_closest of one piece of a ray, in its own parameter (no
/// frame): the walk and tests, inlined.
template <class View>
[[gnu::always_inline]] inline bool closest_piece(const View& view, const Ray& ray, Hit& hit, TraversalScratch& scratch,
                                                 std::uint32_t origin_triangle) {
  hit = Hit{};
  hit.t = ray.tmax;
  const WatertightRay w(ray);
  scratch.mailbox.next_ray();
  const bool found = with_axes(w, [&]<int KX, int KY, int KZ>() {
    return intersect_closest_axes<KX, KY, KZ>(view, ray, w, hit, scratch, origin_triangle);
  });
  if (!found) hit = Hit{};
  return found;
}

/// intersect_any of one piece of a ray (no frame), inlined.
template <class View>
[[gnu::always_inline]] inline bool any_piece(const View& view, const Ray& ray, TraversalScratch& scratch,
                                             std::uint32_t origin_triangle) {
  const WatertightRay w(ray);
  scratch.mailbox.next_ray();
  return with_axes(w, [&]<int KX, int KY, int KZ>() {
    return intersect_any_axes<KX, KY, KZ>(view, ray, w, scratch, origin_triangle);
  });
}

/// closest_piece, out of line: the pieces of a ray split by the frame.
template <class View>
[[gnu::noinline]] bool closest_piece_outlined(const View& view, const Ray& ray, Hit& hit, TraversalScratch& scratch,
                                                std::uint32_t origin_triangle) {
  return closest_piece(view, ray, hit, scratch, origin_triangle);
}

/// any_piece, out of line.
template <class View>
[[gnu::noinline]] bool any_piece_outlined(const View& view, const Ray& ray, TraversalScratch& scratch,
                                            std::uint32_t origin_triangle) {
  return any_piece(view, ray, scratch, origin_triangle);
}

}  // namespace detail

/// Nearest hit of `ray` in (ray.tmin, ray.tmax), an exact tie in t going to
/// the lowest primitive id (tie_bound), so that every grid gives the same
/// hit. Tested in the grid's tracing frame (closest_in_frame). Each
/// primitive is tested at most once per ray piece (mailbox); the walk
/// stops as soon as the best hit lies within the current cell. Returns
/// hit.found(). Precondition: is_valid_ray(ray) (callers reject NaN rays
/// before).
///
/// `origin_triangle`: kNoPrimitive, or the triangle a secondary ray leaves
/// (SurfaceFrame::leaving, shade.h: spawned from a hit on it, to the side
/// of its plane its direction clearly goes), which is then not tested, in
/// every piece of the ray. Its plane lies behind the ray's origin, so the
/// full test refuses it too: the answer is the same either way, without
/// the finish of the candidate that most secondary rays' first cells hold
/// (the surface they start on).
template <class View>
bool intersect_closest(const View& view, const Ray& ray, Hit& hit, TraversalScratch& scratch,
                       std::uint32_t origin_triangle = kNoPrimitive) {
  ++scratch.stats.rays;
  const float frame = view.grid_info().frame_magnitude;
  if (origin_in_frame(frame, ray)) [[likely]]
    return detail::closest_piece(view, ray, hit, scratch, origin_triangle);
  return closest_in_frame(frame, ray, hit, [&](const Ray& piece, Hit& h) {
    return detail::closest_piece_outlined(view, piece, h, scratch, origin_triangle);
  });
}

/// True if anything lies on `ray` in (ray.tmin, ray.tmax): the shadow-ray
/// query, in the grid's tracing frame (any_in_frame). Stops at the first
/// hit found. `origin_triangle` as for intersect_closest.
template <class View>
bool intersect_any(const View& view, const Ray& ray, TraversalScratch& scratch,
                   std::uint32_t origin_triangle = kNoPrimitive) {
  ++scratch.stats.rays;
  const float frame = view.grid_info().frame_magnitude;
  if (origin_in_frame(frame, ray)) [[likely]]
    return detail::any_piece(view, ray, scratch, origin_triangle);
  return any_in_frame(frame, ray, [&](const Ray& piece) {
    return detail::any_piece_outlined(view, piece, scratch, origin_triangle);
  });
}

/// The traversal's entry points over one view type `V`, for explicit
/// instantiation: `RAYNODE_TRAVERSAL_INSTANCES(extern, V)` after V is
/// declared (inside namespace raynode::core) makes every includer call one
/// compiled copy; `RAYNODE_TRAVERSAL_INSTANCES(, V)` in one .cpp compiles it.
/// The walks behind them are most of the build's compile time.
#define RAYNODE_TRAVERSAL_INSTANCES(EXTERN, V)                                                \
  EXTERN template bool intersect_closest<V>(const V&, const Ray&, Hit&, TraversalScratch&, std::uint32_t); \
  EXTERN template bool intersect_any<V>(const V&, const Ray&, TraversalScratch&, std::uint32_t)

}  // namespace raynode::core
