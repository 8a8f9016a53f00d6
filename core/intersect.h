// Ray/primitive intersection tests: watertight triangles, spheres, open cones.
//
// Place in the data flow: the grid traversal (traverse.h) calls these for
// each primitive of each cell it visits; the Embree oracle calls the cone
// test for its user geometry. All tests are two-sided (facing is the
// shader's business) and report a hit only for t in the open interval
// (ray.tmin, tmax).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include "core/database.h"
#include "core/math.h"

namespace raynode::core {

/// Per-ray constants of the watertight triangle test (Woop, Benthin, Wald,
/// "Watertight Ray/Triangle Intersection", JCGT 2(1), 2013): the axis of the
/// largest direction component becomes z, and the shear that maps the
/// direction onto +z.
struct WatertightRay {
  int kx = 0, ky = 1, kz = 2;
  int permutation = 0;  ///< index of (kx, ky, kz) in kAxisPermutations
  float sx = 0, sy = 0, sz = 1;
  /// The ray's largest |direction component| and kNearOrigin times its
  /// largest |origin component| (see refine_unreliable_t), for the
  /// finish's inline near-origin refusal; -inf when built from a direction
  /// alone (the refusal is then left to refine_unreliable_t, which decides
  /// alike on the same products).
  float max_dir = 0, near_origin = -kInfinity;

  /// From the ray: every field, the near-origin ones included.
  explicit WatertightRay(const Ray& ray);

  explicit WatertightRay(const Vec3& dir) {
    const Vec3 a = abs(dir);
    kz = (a.x > a.y) ? (a.x > a.z ? 0 : 2) : (a.y > a.z ? 1 : 2);
    kx = (kz + 1) % 3;
    ky = (kx + 1) % 3;
    bool swapped = false;
    if (dir[kz] < 0.0f) {  // keep the winding: swap x and y
      const int t = kx;
      kx = ky;
      ky = t;
      swapped = true;
    }
    permutation = 2 * kz + (swapped ? 1 : 0);
    sx = dir[kx] / dir[kz];
    sy = dir[ky] / dir[kz];
    sz = 1.0f / dir[kz];
  }
};

namespace detail {
template <int K>
inline float axis(const Vec3& v) {
  if constexpr (K == 0) return v.x;
  else if constexpr (K == 1) return v.y;
  else return v.z;
}
}  // namespace detail

/// Result of a triangle test: distance and barycentrics (p = u*v1 + v*v2 + (1-u-v)*v0).
struct TriangleHit {
  float t, u, v;
};

/// A triangle's edges e1 = v1 - v0, e2 = v2 - v0 and its unnormalised
/// normal n = e1 x e2, in double: the float differences are exact there,
/// the products nearly so, and none overflows or underflows for finite
/// float vertices. The one form of the normal behind the degeneracy test,
/// the plane's t, geometric normals, the floor's slab and validate's
/// referee.
struct TriangleFrameDouble {
  double e1[3], e2[3], n[3];
};

inline TriangleFrameDouble triangle_frame_double(const Vec3& v0, const Vec3& v1, const Vec3& v2) {
  TriangleFrameDouble f;
  for (int i = 0; i < 3; ++i) {
    f.e1[i] = double(v1[i]) - v0[i];
    f.e2[i] = double(v2[i]) - v0[i];
  }
  f.n[0] = f.e1[1] * f.e2[2] - f.e1[2] * f.e2[1];
  f.n[1] = f.e1[2] * f.e2[0] - f.e1[0] * f.e2[2];
  f.n[2] = f.e1[0] * f.e2[1] - f.e1[1] * f.e2[0];
  return f;
}

/// True when the triangle spans (nearly) zero area: |(v1-v0) x (v2-v0)| <=
/// 1e-7 x (longest edge)^2, in double (is_degenerate_polygon's criterion,
/// scene.h). The triangles make_database drops (DatabaseParams::
/// drop_degenerate) and build_grid leaves out of its lists are exactly the
/// ones this rejects; the triangle tests outside the grid's walk call it
/// for would-be hits (rare path).
inline bool triangle_is_degenerate(const Vec3& v0, const Vec3& v1, const Vec3& v2) {
  const TriangleFrameDouble f = triangle_frame_double(v0, v1, v2);
  const double* const e1 = f.e1;
  const double* const e2 = f.e2;
  const double* const n = f.n;
  const double e3[3] = {e2[0] - e1[0], e2[1] - e1[1], e2[2] - e1[2]};
  const double l1 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2];
  const double l2 = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2];
  const double l3 = e3[0] * e3[0] + e3[1] * e3[1] + e3[2] * e3[2];
  const double longest2 = std::max(l1, std::max(l2, l3));
  const double area2 = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  return !(area2 > 1e-7 * longest2);
}

/// Distance from a ray's origin, relative to its largest coordinate (64
/// float spacings), within which a triangle hit whose float t is rounding
/// noise counts as the surface the ray starts on (finish_watertight).
inline constexpr float kNearOrigin = 0x1p-17f;

inline WatertightRay::WatertightRay(const Ray& ray) : WatertightRay(ray.direction) {
  max_dir = max_component(abs(ray.direction));
  // A piece of a ray in the tracing frame starts at a point of the ray's
  // line, not on a surface: nothing is refused there.
  near_origin = is_framed_piece(ray) ? -kInfinity : kNearOrigin * max_component(abs(ray.origin));
}

/// The ray parameter where the ray's line crosses the triangle's plane,
/// t = n.(v0 - o) / n.d with n = (v1 - v0) x (v2 - v0), all in double
/// (the float differences are exact there, the products nearly so), and
/// a bound on its error: `t` and `err` in units of the ray parameter.
/// False when the ray is parallel to the plane. The fallback of
/// finish_watertight where the float t is not good enough, and the source
/// of spawn.h's ray-based hit point.
inline bool triangle_plane_t(const Ray& ray, const Vec3& v0, const Vec3& v1, const Vec3& v2, double& t,
                             double& err) {
  double q[3], d[3];
  for (int i = 0; i < 3; ++i) {
    q[i] = double(v0[i]) - ray.origin[i];
    d[i] = ray.direction[i];
  }
  const TriangleFrameDouble f = triangle_frame_double(v0, v1, v2);
  const double* const n = f.n;
  const double nd = n[0] * d[0] + n[1] * d[1] + n[2] * d[2];
  if (nd == 0.0 || !std::isfinite(nd)) return false;
  const double nq = n[0] * q[0] + n[1] * q[1] + n[2] * q[2];
  t = nq / nd;
  const double mag_q = std::fabs(n[0] * q[0]) + std::fabs(n[1] * q[1]) + std::fabs(n[2] * q[2]);
  const double mag_d = std::fabs(n[0] * d[0]) + std::fabs(n[1] * d[1]) + std::fabs(n[2] * d[2]);
  err = 0x1p-48 * (mag_q + std::fabs(t) * mag_d) / std::fabs(nd);
  return true;
}

namespace detail {

/// Bound on the rounding error of the watertight test's t (in units of the
/// ray parameter), from the values the test computed it from (see
/// finish_watertight). t = sum e_i z_i / sum e_i, so an error d_i in an
/// edge function moves t by sum d_i (z_i - t) / det: by the spread of the
/// vertices' z about t, not by their magnitude (pbrt-v4's bound, PBR 4th
/// ed. §6.8.4, takes the magnitude and rejects every hit on a 1e8 triangle
/// seen from 1e-2 away). The edge functions' error bound is pbrt-v4's
/// (gamma(5) on the sheared coordinates, the shear taken on the unscaled z
/// so that it holds for directions of any length); the z values and the
/// sums add gamma(7) of their magnitudes; the whole is doubled for the
/// first-order terms left out. Relative to the operands throughout: the
/// test answers alike at any scale and position.
/// `max_xt`, `max_yt`: the largest |sheared x| and |sheared y| of the three
/// vertices relative to the origin; `max_zr`: their largest |z| before the
/// scaling by 1/d_z (world units); az, bz, cz: their z after it. The edge
/// functions never have opposite signs here (the sign test came first), so
/// |u| + |v| + |e| = |det| up to det's two roundings: |inv_det| stands for
/// sum |e_i| / |det| with a factor 1 + 2^-21 for those.
/// Generic over the number type F, for which `Ops::abs` acts as std::fabs:
/// floats (triangle_t_error) and a packed cell's eight lanes
/// (cell_blocks.h), which then round alike.
/// `abs_sz` is |1/d_z|: the largest of |az|, |bz|, |cz| is abs_sz x max_zr
/// exactly (rounding is monotonic and the same for both signs). The terms
/// are gathered by hand: delta_e = 2 (g2 + 2 g5) max_xt max_yt + 2 g5
/// max_zr (max_xt + max_yt), each product taken smallest factor first so
/// that it overflows no sooner than the bound itself.
template <class F, class Ops>
[[gnu::always_inline]] inline F triangle_t_error_of(F t, F inv_det, F max_xt, F max_yt, F max_zr, F az, F bz, F cz,
                                                    float abs_sz) {
  constexpr float u1 = 0x1p-24f;
  constexpr float g2 = 2 * u1 / (1 - 2 * u1), g5 = 5 * u1 / (1 - 5 * u1), g7 = 7 * u1 / (1 - 7 * u1);
  constexpr float kSumE = 1 + 0x1p-21f;
  // The whole bound's factor 2 folded in: 2 delta_e, and 2 gamma(7) (1 + 2^-21).
  constexpr float kXY = 4 * (g2 + 2 * g5), kZ = 4 * g5, kMagnitude = 2 * g7 * kSumE;
  const F delta_e2 = kXY * max_xt * max_yt + kZ * max_zr * (max_xt + max_yt);
  const F spread = Ops::abs(az - t) + Ops::abs(bz - t) + Ops::abs(cz - t);
  const F max_z = abs_sz * max_zr;
  return delta_e2 * spread * Ops::abs(inv_det) + kMagnitude * (max_z + Ops::abs(t));
}

/// std::fabs for triangle_t_error_of on floats.
struct ScalarOps {
  static float abs(float x) { return std::fabs(x); }
};

/// triangle_t_error_of on floats.
[[gnu::always_inline]] inline float triangle_t_error(float t, float inv_det, float max_xt, float max_yt,
                                                     float max_zr, float az, float bz, float cz, float abs_sz) {
  return triangle_t_error_of<float, ScalarOps>(t, inv_det, max_xt, max_yt, max_zr, az, bz, cz, abs_sz);
}

/// finish_watertight's answer where the float t is not clearly larger than
/// its error bound `t_err`: false within kNearOrigin float spacings of the
/// origin (a surface the ray was spawned from, or one within rounding of
/// it: not a hit); beyond that the float t is just not good enough (a huge
/// triangle), so the plane is asked in double and `t` becomes its answer
/// when that exceeds its own bound. A piece of a ray in the tracing frame
/// (is_framed_piece) starts at a point of the ray's line, not on a
/// surface: it refuses nothing near its origin, and takes the double t from
/// its tmin on (a floor crossed at the frame's edge, just before or after
/// the piece's origin). Out of line: the callers' loops keep their
/// registers.
[[gnu::noinline]] inline bool refine_unreliable_t(const Ray& ray, float t_err, const Vec3& v0, const Vec3& v1,
                                                  const Vec3& v2, float& t) {
  if (!is_framed_piece(ray) &&
      t_err * max_component(abs(ray.direction)) <= kNearOrigin * max_component(abs(ray.origin)))
    return false;
  double td = 0, err = 0;
  if (!triangle_plane_t(ray, v0, v1, v2, td, err) || !(td - err > std::min(double(ray.tmin), 0.0))) return false;
  t = static_cast<float>(td);
  return true;
}

/// The watertight test's last steps (Woop, Benthin, Wald 2013), after its
/// sign test, shared by every form of the test so that they round alike:
/// from the edge functions u, v, e, the largest |sheared x| and |sheared y|
/// of the three vertices relative to the origin (`max_xt`, `max_yt`), their
/// largest |z| before (`max_zr`, world units) and their z after the scaling
/// by 1/d_z (az, bz, cz), the hit's t,
/// accepted when ray.tmin < t < tmax, then the degeneracy check, then the
/// barycentrics. Where the float t is not clearly larger than its own
/// rounding-error bound (triangle_t_error: an origin lying in or next to
/// the triangle's plane, a grazing ray, a triangle far larger than the
/// distance to the hit), the hit is refused when that bound reaches no
/// further than kNearOrigin of the origin's magnitude (pbrt-v4's rule: the
/// surface the ray was spawned from), else t is recomputed in double from
/// the plane (triangle_plane_t) and the hit counts only if that t exceeds
/// its own, far smaller, bound: an eye in a polygon's plane does not see it
/// at t = 1e-7, and a 1e8 ground seen from 1e-2 away is hit where it is.
/// `kCheckDegenerate` false: the caller's triangles are never degenerate (a
/// grid's lists: build_grid leaves those out), and the check is skipped.
template <bool kCheckDegenerate = true>
[[gnu::always_inline]] inline bool finish_watertight(const Ray& ray, const WatertightRay& w, float u, float v, float e,
                                                     float max_xt, float max_yt, float max_zr, float az, float bz, float cz,
                                                     float tmax, const Vec3& v0, const Vec3& v1, const Vec3& v2,
                                                     TriangleHit& hit) {
  const float det = u + v + e;
  if (det == 0.0f) return false;
  const float t_scaled = u * az + v * bz + e * cz;
  const float inv_det = 1.0f / det;
  float t = t_scaled * inv_det;
  const float t_err = triangle_t_error(t, inv_det, max_xt, max_yt, max_zr, az, bz, cz, std::fabs(w.sz));
  if (!(t_err < 0.5f * std::fabs(t))) [[unlikely]] {
    // refine_unreliable_t's first test on the ray's constants, inline: most
    // unreliable candidates are the surface a secondary ray starts on.
    if (t_err * w.max_dir <= w.near_origin) return false;
    if (!refine_unreliable_t(ray, t_err, v0, v1, v2, t)) return false;
  }
  if (!(t > ray.tmin && t < tmax)) return false;
  if constexpr (kCheckDegenerate)
    if (triangle_is_degenerate(v0, v1, v2)) [[unlikely]] return false;
  hit.t = t;
  hit.u = v * inv_det;  // weight of v1
  hit.v = e * inv_det;  // weight of v2
  return true;
}

}  // namespace detail

/// Watertight ray/triangle test (Woop, Benthin, Wald 2013), one axis
/// permutation. A ray through a shared edge or vertex of a closed mesh hits
/// at least one of the triangles: the edge functions u, v, e of a shared edge
/// are computed identically (negated) from both triangles; those that come
/// out exactly zero are recomputed in double, where the products of floats
/// are exact, so that their sign is the exact one (a float rounding never
/// flips a sign, it only collapses it to zero, which is why a triangle that
/// already has a strictly negative and a strictly positive edge function is
/// rejected before the fallback). Degenerate triangles (triangle_is_degenerate)
/// never hit: in ray space their edge functions are rounding noise that may
/// share a sign. Returns true with `hit` when ray.tmin < t < tmax.
template <int KX, int KY, int KZ>
[[gnu::always_inline]] inline bool intersect_triangle_axes(const Ray& ray, const WatertightRay& w, const Vec3& v0, const Vec3& v1,
                                    const Vec3& v2, float tmax, TriangleHit& hit) {
  using detail::axis;
  const Vec3 a = v0 - ray.origin, b = v1 - ray.origin, c = v2 - ray.origin;
  const float ax = axis<KX>(a) - w.sx * axis<KZ>(a), ay = axis<KY>(a) - w.sy * axis<KZ>(a);
  const float bx = axis<KX>(b) - w.sx * axis<KZ>(b), by = axis<KY>(b) - w.sy * axis<KZ>(b);
  const float cx = axis<KX>(c) - w.sx * axis<KZ>(c), cy = axis<KY>(c) - w.sy * axis<KZ>(c);
  float u = cx * by - cy * bx;
  float v = ax * cy - ay * cx;
  float e = bx * ay - by * ax;
  if (std::min(u, std::min(v, e)) < 0.0f && std::max(u, std::max(v, e)) > 0.0f) return false;
  if (u == 0.0f || v == 0.0f || e == 0.0f) [[unlikely]] {
    u = static_cast<float>(double(cx) * by - double(cy) * bx);
    v = static_cast<float>(double(ax) * cy - double(ay) * cx);
    e = static_cast<float>(double(bx) * ay - double(by) * ax);
    if ((u < 0.0f || v < 0.0f || e < 0.0f) && (u > 0.0f || v > 0.0f || e > 0.0f)) return false;
  }
  auto max_abs = [](float p, float q, float r) { return std::max(std::fabs(p), std::max(std::fabs(q), std::fabs(r))); };
  return detail::finish_watertight(ray, w, u, v, e, max_abs(ax, bx, cx), max_abs(ay, by, cy),
                                   max_abs(axis<KZ>(a), axis<KZ>(b), axis<KZ>(c)), w.sz * axis<KZ>(a),
                                   w.sz * axis<KZ>(b), w.sz * axis<KZ>(c), tmax, v0, v1, v2, hit);
}

/// Watertight ray/triangle test (Woop, Benthin, Wald 2013): see
/// intersect_triangle_axes. Degenerate (zero-area) triangles never hit.
/// Returns true with `hit` when ray.tmin < t < tmax. The axis permutation is a compile-time parameter
/// (one branch per test, the same for the whole ray) so that no vector is
/// indexed by a run-time axis in the inner loop.
inline bool intersect_triangle(const Ray& ray, const WatertightRay& w, const Vec3& v0, const Vec3& v1,
                               const Vec3& v2, float tmax, TriangleHit& hit) {
  switch (w.permutation) {
    case 0: return intersect_triangle_axes<1, 2, 0>(ray, w, v0, v1, v2, tmax, hit);
    case 1: return intersect_triangle_axes<2, 1, 0>(ray, w, v0, v1, v2, tmax, hit);
    case 2: return intersect_triangle_axes<2, 0, 1>(ray, w, v0, v1, v2, tmax, hit);
    case 3: return intersect_triangle_axes<0, 2, 1>(ray, w, v0, v1, v2, tmax, hit);
    case 4: return intersect_triangle_axes<0, 1, 2>(ray, w, v0, v1, v2, tmax, hit);
    default: return intersect_triangle_axes<1, 0, 2>(ray, w, v0, v1, v2, tmax, hit);
  }
}

/// Per-ray constants of intersect_triangle_record_axes broadcast to SSE
/// lanes (origin components in the ray's axis order, shear), built once per
/// ray so that the loop over a cell's triangles does not rebuild them.
/// Empty without SSE2.
struct TriangleRayLanes {
#if defined(__SSE2__)
  __m128 okx, oky, okz, sx, sy, sz;
  TriangleRayLanes(const Ray& ray, const WatertightRay& w)
      : okx(_mm_set1_ps(ray.origin[w.kx])),
        oky(_mm_set1_ps(ray.origin[w.ky])),
        okz(_mm_set1_ps(ray.origin[w.kz])),
        sx(_mm_set1_ps(w.sx)),
        sy(_mm_set1_ps(w.sy)),
        sz(_mm_set1_ps(w.sz)) {}
#else
  TriangleRayLanes(const Ray&, const WatertightRay&) {}
#endif
};

#if defined(__SSE2__)
namespace detail {

/// The end of intersect_triangle_record_axes for a candidate (the ray's line
/// crosses the triangle, or an edge function is 0: rare), out of line so
/// that the per-primitive loop it is called from stays small and keeps its
/// state in registers. Lanes as there: U = (u, v, e), X and Y the sheared
/// vertices, ckz their z relative to the origin, sz = 1/d_z.
template <int KX, int KY, int KZ, bool kCheckDegenerate>
[[gnu::always_inline]] inline bool finish_triangle_lanes(const Ray& ray, const WatertightRay& w, const float* v, __m128 U,
                                             __m128 X, __m128 Y, __m128 ckz, __m128 sz, float tmax,
                                             TriangleHit& hit) {
  if (_mm_movemask_ps(_mm_cmpeq_ps(U, _mm_setzero_ps())) & 7) [[unlikely]]  // an edge function is 0: double fallback
    return intersect_triangle_axes<KX, KY, KZ>(ray, w, Vec3{v[0], v[1], v[2]}, Vec3{v[3], v[4], v[5]},
                                               Vec3{v[6], v[7], v[8]}, tmax, hit);
  // The largest magnitude of lanes 0..2 (lane 3 is no vertex): exact, as in scalar.
  const __m128 magnitude = _mm_castsi128_ps(_mm_set_epi32(0, 0x7fffffff, 0x7fffffff, 0x7fffffff));
  auto max_abs = [&](__m128 x) {
    x = _mm_and_ps(x, magnitude);
    x = _mm_max_ps(x, _mm_shuffle_ps(x, x, _MM_SHUFFLE(2, 3, 0, 1)));
    return _mm_cvtss_f32(_mm_max_ps(x, _mm_shuffle_ps(x, x, _MM_SHUFFLE(1, 0, 3, 2))));
  };
  alignas(16) float uve[4], z[4];
  _mm_store_ps(uve, U);
  _mm_store_ps(z, _mm_mul_ps(sz, ckz));
  return finish_watertight<kCheckDegenerate>(ray, w, uve[0], uve[1], uve[2], max_abs(X), max_abs(Y), max_abs(ckz), z[0],
                                             z[1], z[2], tmax, Vec3{v[0], v[1], v[2]}, Vec3{v[3], v[4], v[5]},
                                             Vec3{v[6], v[7], v[8]}, hit);
}

}  // namespace detail
#endif

/// The watertight triangle test of intersect_triangle_axes on a triangle
/// record's vertex array `v` (v0.xyz v1.xyz v2.xyz, as in Primitive::data;
/// 12 floats must be readable, the last 3 are ignored), with the shear and
/// the edge functions of the three vertices computed side by side in SSE
/// lanes. Every lane performs the scalar test's operations in the scalar
/// test's order (no FMA: -ffp-contract=off), so the answer, t and the
/// barycentrics are bit-identical to intersect_triangle_axes (an edge
/// function exactly 0 goes to it for the double fallback). Without SSE2 it
/// is intersect_triangle_axes. `kCheckDegenerate` false skips the
/// degeneracy check of a would-be hit (finish_watertight): for a grid's
/// lists, which hold no degenerate triangle.
template <int KX, int KY, int KZ, bool kCheckDegenerate = true>
[[gnu::always_inline]] inline bool intersect_triangle_record_axes(const Ray& ray, const WatertightRay& w,
                                                                 const TriangleRayLanes& lanes, const float* v,
                                                                 float tmax, TriangleHit& hit) {
#if defined(__SSE2__)
  // Rows of the 3x3 vertex matrix -> columns (one vector per axis, lanes v0 v1 v2 _).
  const __m128 r0 = _mm_loadu_ps(v), r1 = _mm_loadu_ps(v + 3), r2 = _mm_loadu_ps(v + 6);
  const __m128 zero = _mm_setzero_ps();
  const __m128 t0 = _mm_unpacklo_ps(r0, r1), t1 = _mm_unpackhi_ps(r0, r1);
  const __m128 t2 = _mm_unpacklo_ps(r2, zero), t3 = _mm_unpackhi_ps(r2, zero);
  const __m128 col[3] = {_mm_movelh_ps(t0, t2), _mm_movehl_ps(t2, t0), _mm_movelh_ps(t1, t3)};
  const __m128 ckx = _mm_sub_ps(col[KX], lanes.okx);
  const __m128 cky = _mm_sub_ps(col[KY], lanes.oky);
  const __m128 ckz = _mm_sub_ps(col[KZ], lanes.okz);
  const __m128 X = _mm_sub_ps(ckx, _mm_mul_ps(lanes.sx, ckz));  // (ax, bx, cx, _)
  const __m128 Y = _mm_sub_ps(cky, _mm_mul_ps(lanes.sy, ckz));  // (ay, by, cy, _)
  // Lane i: X[i+2] * Y[i+1] - Y[i+2] * X[i+1] (mod 3) = (u, v, e).
  const __m128 x2 = _mm_shuffle_ps(X, X, _MM_SHUFFLE(3, 1, 0, 2)), y1 = _mm_shuffle_ps(Y, Y, _MM_SHUFFLE(3, 0, 2, 1));
  const __m128 y2 = _mm_shuffle_ps(Y, Y, _MM_SHUFFLE(3, 1, 0, 2)), x1 = _mm_shuffle_ps(X, X, _MM_SHUFFLE(3, 0, 2, 1));
  const __m128 U = _mm_sub_ps(_mm_mul_ps(x2, y1), _mm_mul_ps(y2, x1));
  const int neg = _mm_movemask_ps(_mm_cmplt_ps(U, zero)) & 7, pos = _mm_movemask_ps(_mm_cmpgt_ps(U, zero)) & 7;
  if (neg && pos) return false;
  return detail::finish_triangle_lanes<KX, KY, KZ, kCheckDegenerate>(ray, w, v, U, X, Y, ckz, lanes.sz, tmax, hit);
#else
  return intersect_triangle_axes<KX, KY, KZ>(ray, w, Vec3{v[0], v[1], v[2]}, Vec3{v[3], v[4], v[5]},
                                             Vec3{v[6], v[7], v[8]}, tmax, hit);
#endif
}

/// intersect_triangle_record_axes for the ray's axis permutation: the same
/// answer, t and barycentrics as intersect_triangle on the record's three
/// vertices. `v`: 12 readable floats (Primitive::data of a triangle).
inline bool intersect_triangle_record(const Ray& ray, const WatertightRay& w, const float* v, float tmax,
                                      TriangleHit& hit) {
  const TriangleRayLanes l(ray, w);
  switch (w.permutation) {
    case 0: return intersect_triangle_record_axes<1, 2, 0>(ray, w, l, v, tmax, hit);
    case 1: return intersect_triangle_record_axes<2, 1, 0>(ray, w, l, v, tmax, hit);
    case 2: return intersect_triangle_record_axes<2, 0, 1>(ray, w, l, v, tmax, hit);
    case 3: return intersect_triangle_record_axes<0, 2, 1>(ray, w, l, v, tmax, hit);
    case 4: return intersect_triangle_record_axes<0, 1, 2>(ray, w, l, v, tmax, hit);
    default: return intersect_triangle_record_axes<1, 0, 2>(ray, w, l, v, tmax, hit);
  }
}

/// Ray/sphere test in double precision with the numerically stable quadratic
/// (Haines, Guenther, Akenine-Moeller, "Precision Improvements for
/// Ray/Sphere Intersection", Ray Tracing Gems ch. 7, 2019). Negative radii
/// are treated by their magnitude. Returns the nearest t in (ray.tmin, tmax).
inline bool intersect_sphere(const Ray& ray, const Vec3& center, float radius, float tmax, float& t_out) {
  const double fx = double(ray.origin.x) - center.x, fy = double(ray.origin.y) - center.y,
               fz = double(ray.origin.z) - center.z;
  const double dx = ray.direction.x, dy = ray.direction.y, dz = ray.direction.z;
  const double a = dx * dx + dy * dy + dz * dz;
  const double b = -(fx * dx + fy * dy + fz * dz);  // -b/2 of the usual form
  const double r = double(radius);
  const double c = fx * fx + fy * fy + fz * fz - r * r;
  // Both roots (c/q and q/a below) are <= 0 when b < 0 <= c: the sphere is
  // behind an origin outside it, and no division is needed.
  if (b < 0.0 && c >= 0.0 && ray.tmin >= 0.0f) return false;
  const double s = b / a;
  const double lx = fx + s * dx, ly = fy + s * dy, lz = fz + s * dz;  // closest point - center
  const double disc = a * (r * r - (lx * lx + ly * ly + lz * lz));
  if (disc < 0.0) return false;
  const double q = b + std::copysign(std::sqrt(disc), b);
  const double r_c = (q != 0.0) ? c / q : 0.0;
  // With q, c > 0 both roots are positive and c/q the nearer (up to
  // rounding where they nearly meet): c/q clearly past tmax rules out both
  // without the second division.
  if (q > 0.0 && c > 0.0 && r_c - double(tmax) > 0x1p-40 * r_c) return false;
  double t0 = r_c, t1 = q / a;
  if (t0 > t1) std::swap(t0, t1);
  if (q == 0.0) t0 = t1;
  const double lo = ray.tmin, hi = tmax;
  if (t0 > lo && t0 < hi) {
    t_out = static_cast<float>(t0);
    return t_out > ray.tmin && t_out < tmax;
  }
  if (t1 > lo && t1 < hi) {
    t_out = static_cast<float>(t1);
    return t_out > ray.tmin && t_out < tmax;
  }
  return false;
}

/// Ray test against an open cone or cylinder (no caps) from `base` (radius
/// rb) to `apex` (radius ra), in double precision. Radii are taken by
/// magnitude. Returns the nearest t in (ray.tmin, tmax) whose point lies
/// between the two end planes.
inline bool intersect_cone(const Ray& ray, const Vec3& base, float rb_in, const Vec3& apex, float ra_in,
                           float tmax, float& t_out) {
  const double rb = std::fabs(double(rb_in)), ra = std::fabs(double(ra_in));
  // The axis W = apex - base is left unnormalised (exact in double: a
  // difference of floats); projections onto it are taken as fractions of
  // the axis, f = (P . W) / |W|^2, so the test needs no square root and one
  // division.
  const double w[3] = {double(apex.x) - base.x, double(apex.y) - base.y, double(apex.z) - base.z};
  const double h2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
  if (!(h2 > 0.0)) return false;
  const double inv_h2 = 1.0 / h2;
  const double o[3] = {double(ray.origin.x) - base.x, double(ray.origin.y) - base.y,
                       double(ray.origin.z) - base.z};
  const double d[3] = {ray.direction.x, ray.direction.y, ray.direction.z};
  const double fo = (o[0] * w[0] + o[1] * w[1] + o[2] * w[2]) * inv_h2;  // the origin's axial fraction
  const double fd = (d[0] * w[0] + d[1] * w[1] + d[2] * w[2]) * inv_h2;  // its change per unit t
  double op[3], dp[3];  // the parts of o and d normal to the axis
  for (int i = 0; i < 3; ++i) {
    op[i] = o[i] - fo * w[i];
    dp[i] = d[i] - fd * w[i];
  }
  // Radius at axial fraction f: rb + c f. The surface: |op + t dp|^2 =
  // (r0 + c fd t)^2 with r0 the radius at the origin's axial position.
  const double c = ra - rb;
  const double r0 = rb + c * fo;
  const double cfd = c * fd;
  const double qa = dp[0] * dp[0] + dp[1] * dp[1] + dp[2] * dp[2] - cfd * cfd;
  const double qb = 2.0 * (op[0] * dp[0] + op[1] * dp[1] + op[2] * dp[2] - r0 * cfd);
  const double qc = op[0] * op[0] + op[1] * op[1] + op[2] * op[2] - r0 * r0;
  // The stable pair of roots (Press et al., "Numerical Recipes", §5.6):
  // q = -(qb + sign(qb) sqrt(disc)) / 2, t = q / qa and t = qc / q. No
  // tolerance decides whether the quadratic is "really" linear: as qa -> 0
  // (a ray parallel to a cylinder's side or to a cone's slant line) q / qa
  // goes to infinity on its own and qc / q stays the finite root, at any
  // scale and for directions of any length.
  const double disc = qb * qb - 4.0 * qa * qc;
  if (disc < 0.0) return false;
  const double q = -0.5 * (qb + std::copysign(std::sqrt(disc), qb));
  if (q == 0.0) return false;  // qb = 0 and qa qc = 0: no isolated root
  double roots[2] = {qc / q, qa != 0.0 ? q / qa : kInfinity};
  if (roots[0] > roots[1]) std::swap(roots[0], roots[1]);
  for (const double t : roots) {
    if (!(t > ray.tmin && t < tmax)) continue;
    const double f = fo + t * fd;  // axial fraction of the hit
    if (f < 0.0 || f > 1.0) continue;
    if (rb + c * f < 0.0) continue;  // the other nappe of a cone
    const float tf = static_cast<float>(t);
    if (!(tf > ray.tmin && tf < tmax)) continue;
    t_out = tf;
    return true;
  }
  return false;
}

/// a / |a| computed in double, rounded to float; (0,0,0) for a zero,
/// infinite or NaN vector.
Vec3 unit_from_double(const double a[3]);

/// Unit geometric normal (not face-forwarded) of primitive `p` at world
/// point `hit_point`, computed in double so that no squared length
/// overflows or underflows (triangles with edges of 1e10 and more, or of
/// 1e-20 and less); (0,0,0) for a degenerate primitive.
Vec3 geometric_normal(const Primitive& p, const Vec3& hit_point);

}  // namespace raynode::core
