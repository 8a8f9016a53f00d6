// raynode core math: 3-vectors, rays and axis-aligned boxes in single precision.
//
// Place in the data flow: every other core file (scene model, primitives, grid,
// tracer) speaks in these types. World units throughout; directions need not be
// normalised unless a function says so.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace raynode::core {

inline constexpr float kInfinity = std::numeric_limits<float>::infinity();

/// A 3-vector of floats (point, direction or colour). Trivially copyable, 12 bytes.
struct Vec3 {
  float x = 0.0f, y = 0.0f, z = 0.0f;

  constexpr Vec3() = default;
  constexpr Vec3(float x_, float y_, float z_) : x(x_), y(y_), z(z_) {}

  /// Component by axis index 0..2 (x, y, z).
  constexpr float operator[](int axis) const { return axis == 0 ? x : (axis == 1 ? y : z); }
  constexpr float& operator[](int axis) { return axis == 0 ? x : (axis == 1 ? y : z); }

  constexpr Vec3 operator-() const { return {-x, -y, -z}; }
  constexpr Vec3& operator+=(const Vec3& b) { x += b.x; y += b.y; z += b.z; return *this; }
  constexpr Vec3& operator-=(const Vec3& b) { x -= b.x; y -= b.y; z -= b.z; return *this; }
  constexpr Vec3& operator*=(float s) { x *= s; y *= s; z *= s; return *this; }
  friend constexpr bool operator==(const Vec3&, const Vec3&) = default;
};

constexpr Vec3 operator+(Vec3 a, const Vec3& b) { return a += b; }
constexpr Vec3 operator-(Vec3 a, const Vec3& b) { return a -= b; }
constexpr Vec3 operator*(Vec3 a, float s) { return a *= s; }
constexpr Vec3 operator*(float s, Vec3 a) { return a *= s; }
/// Component-wise product (colours).
constexpr Vec3 operator*(const Vec3& a, const Vec3& b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
constexpr Vec3 operator/(const Vec3& a, float s) { return {a.x / s, a.y / s, a.z / s}; }

constexpr float dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
constexpr Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline float length(const Vec3& a) { return std::sqrt(dot(a, a)); }
/// |a| in double precision: finite for every finite a (|a|^2 overflows float beyond ~1.8e19).
inline double length_double(const Vec3& a) {
  return std::sqrt(double(a.x) * a.x + double(a.y) * a.y + double(a.z) * a.z);
}
/// Unit vector along a; a must be non-zero (a zero vector gives NaNs).
inline Vec3 normalize(const Vec3& a) { return a * (1.0f / length(a)); }
constexpr Vec3 min(const Vec3& a, const Vec3& b) {
  return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)};
}
constexpr Vec3 max(const Vec3& a, const Vec3& b) {
  return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)};
}
inline Vec3 abs(const Vec3& a) { return {std::fabs(a.x), std::fabs(a.y), std::fabs(a.z)}; }
constexpr float max_component(const Vec3& a) { return std::max(a.x, std::max(a.y, a.z)); }
/// floor(v) clamped to [0, n - 1], n >= 1, clamped before the conversion to
/// int (converting an out-of-range or NaN value is undefined behaviour: cells
/// of a tiny grid, points far outside it); NaN gives 0.
inline int clamped_floor(double v, int n) {
  const double f = std::floor(v);
  return f >= double(n - 1) ? n - 1 : (f > 0.0 ? static_cast<int>(f) : 0);
}
/// clamped_floor of a float, in float (the same result; n - 1 < 2^24).
inline int clamped_floor(float v, int n) {
  const float f = std::floor(v);
  return f >= float(n - 1) ? n - 1 : (f > 0.0f ? static_cast<int>(f) : 0);
}
/// Unit vector along a for every finite non-zero a: normalize(a), bit for
/// bit, when |a|^2 is a normal float; else a divided by its largest
/// magnitude first, so that |a|^2 neither overflows (|a| beyond ~1.8e19,
/// e.g. a camera far from its target) nor underflows.
inline Vec3 normalize_any(const Vec3& a) {
  const float d = dot(a, a);
  if (d >= std::numeric_limits<float>::min() && d <= std::numeric_limits<float>::max()) return normalize(a);
  const float m = max_component(abs(a));
  if (!(m > 0.0f) || !std::isfinite(m)) return normalize(a);  // zero or not finite: NaNs, as normalize
  return normalize(Vec3{a.x / m, a.y / m, a.z / m});
}
inline bool is_finite(const Vec3& a) {
  return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z);
}

/// Axis-aligned box; default-constructed empty (lower > upper).
struct Bounds3 {
  Vec3 lower{kInfinity, kInfinity, kInfinity};
  Vec3 upper{-kInfinity, -kInfinity, -kInfinity};

  constexpr bool empty() const { return lower.x > upper.x || lower.y > upper.y || lower.z > upper.z; }
  constexpr void extend(const Vec3& p) { lower = min(lower, p); upper = max(upper, p); }
  constexpr void extend(const Bounds3& b) { lower = min(lower, b.lower); upper = max(upper, b.upper); }
  constexpr Vec3 extent() const { return upper - lower; }
  constexpr Vec3 center() const { return (lower + upper) * 0.5f; }
  constexpr bool overlaps(const Bounds3& b) const {
    return lower.x <= b.upper.x && b.lower.x <= upper.x && lower.y <= b.upper.y &&
           b.lower.y <= upper.y && lower.z <= b.upper.z && b.lower.z <= upper.z;
  }
};

/// A ray: points origin + t * direction for t in [tmin, tmax]. The direction
/// need not be unit length (t is then in units of |direction|), but must be
/// finite and non-zero; use `is_valid_ray` to reject NaN/inf/zero input.
struct Ray {
  Vec3 origin;
  Vec3 direction;
  float tmin = 0.0f;
  float tmax = kInfinity;

  constexpr Vec3 at(float t) const { return origin + direction * t; }
};

/// True for a piece of a ray in the tracing frame (framed_ray, traverse.h):
/// it starts at a point of the ray's line, not on a surface, and its tmin
/// < 0 reaches back to where the line enters the frame. Such a piece
/// refuses no hit near its origin (finish_watertight).
inline bool is_framed_piece(const Ray& r) { return r.tmin < 0.0f; }

/// True when origin and direction are finite, direction non-zero, and
/// 0 <= tmin <= tmax (tmax may be +inf). NaN rays are rejected here.
inline bool is_valid_ray(const Ray& r) {
  return is_finite(r.origin) && is_finite(r.direction) && dot(r.direction, r.direction) > 0.0f &&
         r.tmin >= 0.0f && r.tmin <= r.tmax && !std::isnan(r.tmax);
}

/// Slab test of a ray against a box, in the ray's parameter. On overlap
/// returns true with [t0, t1] the clipped interval within [r.tmin, r.tmax].
/// Zero direction components are handled (inf reciprocal; NaN from 0*inf is
/// avoided by the min/max ordering). Robust: the far bound is inflated by
/// 2 gamma(3) as in pbrt (Ize 2013), so a ray grazing a face is not lost.
inline bool intersect_bounds(const Bounds3& b, const Ray& r, const Vec3& inv_dir, float& t0, float& t1) {
  t0 = r.tmin;
  t1 = r.tmax;
  for (int a = 0; a < 3; ++a) {
    float lo = (b.lower[a] - r.origin[a]) * inv_dir[a];
    float hi = (b.upper[a] - r.origin[a]) * inv_dir[a];
    if (r.direction[a] == 0.0f) {
      // Parallel to the slab: inside or not, independent of t.
      if (r.origin[a] < b.lower[a] || r.origin[a] > b.upper[a]) return false;
      continue;
    }
    if (lo > hi) std::swap(lo, hi);
    hi *= 1.0f + 2.0f * 3.0f * std::numeric_limits<float>::epsilon();
    t0 = lo > t0 ? lo : t0;
    t1 = hi < t1 ? hi : t1;
    if (t0 > t1) return false;
  }
  return true;
}

}  // namespace raynode::core
