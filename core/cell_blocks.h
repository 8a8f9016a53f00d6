// Packed cell triangles: a grid cell's triangles copied beside each other in
// SIMD blocks (structure of arrays, kBlockLanes triangles a block), so that
// one vector test answers for a whole block and a dense cell reads its
// triangles in order, not by id from the primitive array. This is the
// "triangle4/8" idea of Embree's leaves (Wald et al., "Embree: a kernel
// framework for efficient CPU ray tracing", SIGGRAPH 2014) applied to the
// cells of a uniform grid. Cells of spheres are packed alike (SphereBlock),
// in the in-process views only, under a memory cap (build_cell_blocks).
//
// Place in the data flow: Database + Grid -> build_cell_blocks -> CellBlocks
// -> DatabaseArrays / DirectView (direct_view.h) -> the one tracer
// (traverse.h) tests a packed cell's blocks instead of walking its list.
// Views over plain arrays have them (sequential and shared modes, the accel
// bench, validate); svm pages them when asked (--pack-cells N with --mode
// svm, svm/paged_database.h), and otherwise, like dataflow's regions, holds
// the paper's object lists, tested with the same answers.
//
// Same answers: every lane performs intersect_triangle_axes's float
// operations in its order (no FMA: -ffp-contract=off); the lanes whose ray
// line crosses their triangle finish in the block's lanes too, in
// finish_watertight's order (finish_block), and an edge function exactly 0
// goes to intersect_triangle_axes itself. Lanes are taken
// in list order with the running nearest t as the bound (tie_bound), so the
// hit (t, u, v and primitive, an exact tie to the lowest id) is the one the
// list walk finds.
// A packed triangle cell does not use the ray's mailbox: testing a block
// again costs less than looking its ids up, and a second test of a
// primitive can never replace the hit (its t is not below the nearest found
// since). A packed sphere cell culls its lanes in float first and sends the
// survivors through the mailbox to the exact test (intersect_cell_spheres).
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <vector>

#if defined(__AVX__)
#include <immintrin.h>
#endif

#include "core/database.h"
#include "core/grid.h"
#include "core/intersect.h"
#include "core/math.h"

namespace raynode::core {

/// Triangles per block.
inline constexpr std::uint32_t kBlockLanes = 8;

/// kBlockLanes triangles, coordinates by vertex and axis, lane by lane.
/// Lanes past the cell's count hold zeros and are never reported.
struct alignas(32) TriangleBlock {
  float v[3][3][kBlockLanes];           ///< [vertex 0..2][axis x,y,z][lane], world units
  std::uint32_t primitive[kBlockLanes];  ///< primitive id of each lane
};
static_assert(sizeof(TriangleBlock) == 320);

/// kBlockLanes spheres, centres by axis and radii, lane by lane (the
/// primitives' float values as stored, radii with their sign). Lanes past
/// the cell's count hold zeros and are never reported.
struct alignas(32) SphereBlock {
  float center[3][kBlockLanes];          ///< [axis x,y,z][lane], world units
  float radius[kBlockLanes];             ///< world units, signed as in the primitive
  std::uint32_t primitive[kBlockLanes];  ///< primitive id of each lane
};
static_assert(sizeof(SphereBlock) == 160);

/// The packed cells of a grid. A cell is packed when it lists at least
/// `min_triangles` primitives and all of them are triangles (or, when
/// spheres are packed, all spheres); its blocks are blocks[start[c] ..
/// start[c+1]) (sphere_blocks[sphere_start[c] .. sphere_start[c+1])), its
/// primitives in list order, the last block holding count - kBlockLanes *
/// (blocks - 1) of them.
struct CellBlocks {
  std::vector<std::uint32_t> start;   ///< cell_count()+1 offsets into blocks
  std::vector<TriangleBlock> blocks;  ///< 32-byte aligned
  std::vector<std::uint32_t> sphere_start;  ///< cell_count()+1 offsets into sphere_blocks, or empty: none packed
  std::vector<SphereBlock> sphere_blocks;   ///< 32-byte aligned
  std::uint32_t min_triangles = 0;    ///< the packing threshold it was built with (primitives per cell)
  std::size_t bytes() const {
    return start.size() * sizeof(std::uint32_t) + blocks.size() * sizeof(TriangleBlock) +
           sphere_start.size() * sizeof(std::uint32_t) + sphere_blocks.size() * sizeof(SphereBlock);
  }
};

/// Default least primitive count of a packed cell (`--pack-cells`); chosen
/// with `raynode bench accel` (see docs/results.md).
inline constexpr std::uint32_t kDefaultPackMin = 3;

/// Which cells build_cell_blocks packs: triangle cells only (what svm's
/// paged layout holds), or sphere cells too (the in-process views).
enum class PackKinds { kTriangles, kTrianglesAndSpheres };

/// Packs the cells of `grid` (over `db`) that list at least `min_triangles`
/// (>= 1) primitives, all triangles, or with kTrianglesAndSpheres all
/// spheres. Sphere blocks are capped at 4 times the blocks that would hold
/// each sphere once, the cells with the longest lists packed first: a
/// sphere is copied into every packed cell listing it, and large
/// overlapping spheres (SPD shells: 93 times) would outgrow the cache and
/// trace slower than the lists. Throws std::invalid_argument for
/// min_triangles == 0, std::length_error past 2^32 blocks.
CellBlocks build_cell_blocks(const Database& db, const Grid& grid, std::uint32_t min_triangles = kDefaultPackMin,
                             PackKinds kinds = PackKinds::kTriangles);

/// A packed cell's view: its blocks and how many triangles they hold.
struct CellBlockSpan {
  const TriangleBlock* blocks = nullptr;
  std::uint32_t block_count = 0;
  std::uint32_t triangles = 0;
};

/// A packed sphere cell's view: its blocks and how many spheres they hold.
struct SphereBlockSpan {
  const SphereBlock* blocks = nullptr;
  std::uint32_t block_count = 0;
  std::uint32_t spheres = 0;
};

namespace detail {

// GCC/Clang vector extensions: AVX registers where the target has them.
using LaneF = float __attribute__((vector_size(4 * kBlockLanes)));
using LaneI = std::int32_t __attribute__((vector_size(4 * kBlockLanes)));

inline std::uint32_t lane_bits(LaneI m) {
#if defined(__AVX__)
  static_assert(kBlockLanes == 8);
  return std::uint32_t(_mm256_movemask_ps(reinterpret_cast<__m256>(m)));
#else
  std::uint32_t bits = 0;
  for (std::uint32_t i = 0; i < kBlockLanes; ++i) bits |= std::uint32_t(m[i] & 1) << i;
  return bits;
#endif
}

/// A block's values of the watertight test, lane by lane: the edge
/// functions, the sheared x and y of the three vertices relative to the
/// origin, and their z relative to it (world units, before the scaling).
struct BlockLanes {
  LaneF u, v, e;
  LaneF x[3], y[3], z[3];
};

/// The candidate lanes of `b` (the ray's line crosses the triangle, or an
/// edge function is 0), with each lane's values in `l`.
template <int KX, int KY, int KZ>
[[gnu::always_inline]] inline std::uint32_t block_candidates(const TriangleBlock& b, const float o[3],
                                                            const WatertightRay& w, BlockLanes& l) {
  const LaneF* const c = reinterpret_cast<const LaneF*>(b.v);  // c[3 * vertex + axis]
  const LaneF ax = c[0 + KX] - o[KX], ay = c[0 + KY] - o[KY], az = c[0 + KZ] - o[KZ];
  const LaneF bx = c[3 + KX] - o[KX], by = c[3 + KY] - o[KY], bz = c[3 + KZ] - o[KZ];
  const LaneF cx = c[6 + KX] - o[KX], cy = c[6 + KY] - o[KY], cz = c[6 + KZ] - o[KZ];
  const LaneF Ax = ax - w.sx * az, Ay = ay - w.sy * az;
  const LaneF Bx = bx - w.sx * bz, By = by - w.sy * bz;
  const LaneF Cx = cx - w.sx * cz, Cy = cy - w.sy * cz;
  const LaneF u = Cx * By - Cy * Bx;
  const LaneF v = Ax * Cy - Ay * Cx;
  const LaneF e = Bx * Ay - By * Ax;
  l = BlockLanes{u, v, e, {Ax, Bx, Cx}, {Ay, By, Cy}, {az, bz, cz}};
  const LaneF zero = {};
  const LaneI neg = (u < zero) | (v < zero) | (e < zero);
  const LaneI pos = (u > zero) | (v > zero) | (e > zero);
  return ~lane_bits(neg & pos) & ((1u << kBlockLanes) - 1);
}

/// The triangle of lane `l` of `b`.
inline void block_triangle(const TriangleBlock& b, std::uint32_t l, Vec3& v0, Vec3& v1, Vec3& v2) {
  v0 = Vec3{b.v[0][0][l], b.v[0][1][l], b.v[0][2][l]};
  v1 = Vec3{b.v[1][0][l], b.v[1][1][l], b.v[1][2][l]};
  v2 = Vec3{b.v[2][0][l], b.v[2][1][l], b.v[2][2][l]};
}

/// Lane by lane, the largest magnitude of three lanes' values (exact).
[[gnu::always_inline]] inline LaneF max_abs_lanes(const LaneF (&x)[3]) {
  auto mag = [](LaneF a) { return reinterpret_cast<LaneF>(reinterpret_cast<LaneI>(a) & 0x7fffffff); };
  const LaneF a = mag(x[0]), b = mag(x[1]), c = mag(x[2]);
  const LaneF ab = a > b ? a : b;
  return ab > c ? ab : c;
}

/// std::fabs lane by lane, for triangle_t_error_of.
struct LaneOps {
  static LaneF abs(LaneF a) { return reinterpret_cast<LaneF>(reinterpret_cast<LaneI>(a) & 0x7fffffff); }
};

/// finish_block's answers, lane by lane: t, the barycentrics (u = weight of
/// v1, v = weight of v2) and t's error bound, and which of the lanes it
/// hands on need the double fallback (zero_edge) or refine_unreliable_t
/// (unreliable).
struct BlockFinish {
  alignas(32) float t[kBlockLanes], u[kBlockLanes], v[kBlockLanes], t_err[kBlockLanes];
  std::uint32_t zero_edge = 0, unreliable = 0;
};

/// finish_watertight's float steps on the candidate lanes of a block
/// (`candidates`, from block_candidates' values `l`), eight at once and in
/// its order of operations: the same t, t error bound and barycentrics, bit
/// for bit, written to `f`. Returns the lanes the scalar loop must still
/// look at: an edge function exactly 0 (the double fallback of
/// intersect_triangle_axes), a t not clearly above its error bound that
/// lies beyond kNearOrigin of the origin (refine_unreliable_t), and a
/// reliable t in (tmin, hit_t] (a hit once checked against the exact
/// bound: hit_t only shrinks while the block's lanes are taken). The
/// others miss whatever happens next: a reliable t outside that interval,
/// an unreliable one near the origin, det = 0.
template <int KX, int KY, int KZ>
[[gnu::always_inline]] inline std::uint32_t finish_block(const BlockLanes& l, std::uint32_t candidates,
                                                          const Ray& ray, const WatertightRay& w, float hit_t,
                                                          BlockFinish& f) {
  const LaneF zero = {};
  const LaneI zero_edge = (l.u == zero) | (l.v == zero) | (l.e == zero);
  const LaneF det = l.u + l.v + l.e;
  const LaneF az = w.sz * l.z[0], bz = w.sz * l.z[1], cz = w.sz * l.z[2];
  const LaneF t_scaled = l.u * az + l.v * bz + l.e * cz;
  const LaneF inv_det = 1.0f / det;
  const LaneF t = t_scaled * inv_det;
  const LaneF t_err = triangle_t_error_of<LaneF, LaneOps>(t, inv_det, max_abs_lanes(l.x), max_abs_lanes(l.y),
                                                          max_abs_lanes(l.z), az, bz, cz, std::fabs(w.sz));
  const LaneI reliable = t_err < 0.5f * LaneOps::abs(t);
  const LaneI in_range = (t > ray.tmin) & (t <= hit_t);
  const LaneI near_origin = t_err * w.max_dir <= w.near_origin;
  const std::uint32_t zero_bits = lane_bits(zero_edge) & candidates;
  const std::uint32_t unreliable_bits = lane_bits(~reliable & ~near_origin & (det != zero)) & candidates & ~zero_bits;
  const std::uint32_t keep = zero_bits | unreliable_bits | (lane_bits(reliable & in_range) & candidates);
  if (!keep) return 0;
  const LaneF u = l.v * inv_det, v = l.e * inv_det;
  std::memcpy(f.t, &t, sizeof f.t);
  std::memcpy(f.u, &u, sizeof f.u);
  std::memcpy(f.v, &v, sizeof f.v);
  std::memcpy(f.t_err, &t_err, sizeof f.t_err);
  f.zero_edge = zero_bits;
  f.unreliable = unreliable_bits;
  return keep;
}

/// The bound the nearest-hit query tests primitive `id` against, given the
/// nearest hit so far (t, primitive): t, or for an id below `primitive`
/// the next float above t, so that a hit at exactly t goes to the lowest
/// id whatever cells and lists a grid tests the primitives in: the tied
/// primitives pass through the hit's point, so the cell holding it lists
/// them all, and the walk stops only after that cell. Images are then the
/// same over any grid (adaptive or uniform, of any density, or a dataflow
/// region's). `primitive` is 0 while there is no hit (no id is below it);
/// t > ray.tmin >= 0 once there is one.
[[gnu::always_inline]] inline float tie_bound(float t, std::uint32_t primitive, std::uint32_t id) {
  return id < primitive ? std::bit_cast<float>(std::bit_cast<std::uint32_t>(t) + 1) : t;
}

/// Tests a packed cell's triangles in list order against `ray`; on a hit
/// nearer than hit.t, or as near with a lower id (tie_bound; hit_primitive
/// 0 while there is no hit), updates `hit` (closest) and returns true. `any`: stop
/// at the first hit in (ray.tmin, hit.t). The lane of `origin_triangle`
/// (the triangle the ray leaves, or kNoPrimitive: intersect_closest) is
/// no candidate. Adds the triangles tested to `triangle_tests`.
template <int KX, int KY, int KZ, bool kAny>
[[gnu::always_inline]] inline bool intersect_cell_blocks(const CellBlockSpan& cell, const Ray& ray,
                                                        const WatertightRay& w, std::uint32_t origin_triangle,
                                                        float& hit_t, float& hit_u,
                                                        float& hit_v, std::uint32_t& hit_primitive,
                                                        std::uint64_t& triangle_tests) {
  triangle_tests += cell.triangles;
  const float o[3] = {ray.origin.x, ray.origin.y, ray.origin.z};
  bool found = false;
  std::uint32_t left = cell.triangles;
  for (std::uint32_t k = 0; k < cell.block_count; ++k, left -= kBlockLanes) {
    const TriangleBlock& b = cell.blocks[k];
    BlockLanes bl;
    std::uint32_t bits = block_candidates<KX, KY, KZ>(b, o, w, bl);
    if (left < kBlockLanes) bits &= (1u << left) - 1;
    if (!bits) [[likely]] continue;
    // The surface a secondary ray starts on is the candidate of most blocks
    // that have one: dropped by id, the block needs no finish.
    bits &= ~lane_bits(*reinterpret_cast<const LaneI*>(b.primitive) == std::int32_t(origin_triangle));
    if (!bits) continue;
    // Candidates (rare): finished eight at once; the few lanes left are hits
    // or need a scalar step.
    BlockFinish f;
    bits = finish_block<KX, KY, KZ>(bl, bits, ray, w, hit_t, f);
    while (bits) {
      const std::uint32_t l = std::uint32_t(__builtin_ctz(bits));
      const std::uint32_t lane = bits & -bits;
      bits &= bits - 1;
      const float tmax = kAny ? hit_t : tie_bound(hit_t, hit_primitive, b.primitive[l]);
      TriangleHit th{f.t[l], f.u[l], f.v[l]};
      if ((f.zero_edge | f.unreliable) & lane) [[unlikely]] {
        Vec3 v0, v1, v2;
        block_triangle(b, l, v0, v1, v2);
        if (f.zero_edge & lane) {
          if (!intersect_triangle_axes<KX, KY, KZ>(ray, w, v0, v1, v2, tmax, th)) continue;
        } else if (!refine_unreliable_t(ray, f.t_err[l], v0, v1, v2, th.t)) {
          continue;
        }
      }
      if (!(th.t > ray.tmin && th.t < tmax)) continue;
      hit_t = th.t;
      hit_u = th.u;
      hit_v = th.v;
      hit_primitive = b.primitive[l];
      found = true;
      if constexpr (kAny) return true;
    }
  }
  return found;
}

/// Tests a packed sphere cell's spheres in list order against `ray`, with
/// intersect_sphere's answers: on a hit nearer than hit_t, or as near with
/// a lower id (tie_bound), updates the hit (u = v = 0) and returns true. `any`: stop at the first hit in
/// (ray.tmin, hit_t). Adds the spheres tested to `sphere_tests`.
///
/// Each block first goes through a conservative float cull, eight lanes at
/// once: a lane is dropped only when the ray's line passes farther from the
/// centre than |r| + delta, or when the interval of t where the line is
/// within |r| + 2 delta of the centre ends before ray.tmin or starts after
/// hit_t. delta = 1e-5 (max |c - o|_i + |r|) is over a hundred times the
/// float rounding error of the values compared (each is a few operations on
/// c - o and d, whose errors are relative to |c - o| and |r|). Comparisons
/// are written so that a NaN or an overflow keeps the lane (and a floor of
/// 1e-35 on the squared distance keeps it near float's underflow), and the
/// surviving lanes run intersect_sphere itself: the same hits, t and
/// primitive as the list walk, whatever the cull lets through. A surviving
/// lane goes through the ray's `mailbox` (Mailbox::Probe, traverse.h), so a
/// large sphere listed in many cells costs one exact test per ray.
template <bool kAny, class MailboxProbe>
[[gnu::always_inline]] inline bool intersect_cell_spheres(const SphereBlockSpan& cell, const Ray& ray,
                                                         MailboxProbe& mailbox,
                                                         float& hit_t, float& hit_u, float& hit_v,
                                                         std::uint32_t& hit_primitive, std::uint64_t& sphere_tests,
                                                         std::uint64_t& mailbox_skips) {
  sphere_tests += cell.spheres;
  const float dx = ray.direction.x, dy = ray.direction.y, dz = ray.direction.z;
  const float inv_a = 1.0f / (dx * dx + dy * dy + dz * dz);
  const LaneF zero = {};
  const auto mag = [](LaneF a) { return reinterpret_cast<LaneF>(reinterpret_cast<LaneI>(a) & 0x7fffffff); };
  bool found = false;
  std::uint32_t left = cell.spheres;
  for (std::uint32_t k = 0; k < cell.block_count; ++k, left -= kBlockLanes) {
    const SphereBlock& b = cell.blocks[k];
    const LaneF* const c = reinterpret_cast<const LaneF*>(b.center);
    const LaneF gx = c[0] - ray.origin.x, gy = c[1] - ray.origin.y, gz = c[2] - ray.origin.z;
    const LaneF r = mag(*reinterpret_cast<const LaneF*>(b.radius));
    const LaneF s = (gx * dx + gy * dy + gz * dz) * inv_a;  // t of the point nearest the centre
    const LaneF lx = gx - s * dx, ly = gy - s * dy, lz = gz - s * dz;
    const LaneF dist2 = lx * lx + ly * ly + lz * lz;
    const LaneF mx = mag(gx), my = mag(gy), mz = mag(gz);
    const LaneF m = (mx > my ? (mx > mz ? mx : mz) : (my > mz ? my : mz)) + r;
    const LaneF delta = m * 1e-5f;
    const LaneF near = r + delta, reach = r + 2.0f * delta;
    const LaneF reach2 = reach * reach * inv_a;
    const LaneF before = ray.tmin - s, after = s - hit_t;
    const LaneI miss = (dist2 > near * near + 1e-35f) | ((before > zero) & (before * before > reach2)) |
                       ((after > zero) & (after * after > reach2));
    std::uint32_t bits = lane_bits(~miss);
    if (left < kBlockLanes) bits &= (1u << left) - 1;
    while (bits) {
      const std::uint32_t l = std::uint32_t(__builtin_ctz(bits));
      bits &= bits - 1;
      if (mailbox.seen_or_insert(b.primitive[l])) {
        ++mailbox_skips;
        continue;
      }
      float t;
      const float tmax = kAny ? hit_t : tie_bound(hit_t, hit_primitive, b.primitive[l]);
      if (!intersect_sphere(ray, Vec3{b.center[0][l], b.center[1][l], b.center[2][l]}, b.radius[l], tmax, t))
        continue;
      hit_t = t;
      hit_u = 0;
      hit_v = 0;
      hit_primitive = b.primitive[l];
      found = true;
      if constexpr (kAny) return true;
    }
  }
  return found;
}

}  // namespace detail

}  // namespace raynode::core
