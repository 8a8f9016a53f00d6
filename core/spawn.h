// Where secondary rays start: a hit point with a bound on its floating-point
// error, and a ray origin offset just past that bound.
//
// Place in the data flow: closest hit (traverse.h) -> surface_frame
// (shade.h) -> hit_point -> offset_ray_origin -> the shadow, reflected and
// refracted rays of every mode (core's trace_ray, dataflow's shade) and the
// secondary rays of `raynode validate` and `bench accel`.
//
// No tolerance here is absolute: every bound is a multiple of the unit
// roundoff times the magnitudes of the operands, so a scene renders the same
// at any scale, and moved anywhere that floats still resolve it.
// Source: Pharr, Jakob, Humphreys, "Physically Based Rendering", 4th ed.,
// §6.8 "Managing Rounding Error" (error bounds of the reconstructed hit
// point; OffsetRayOrigin), with Higham's gamma(n) bound.
#pragma once

#include <bit>
#include <cmath>
#include <cstdint>

#include "core/database.h"
#include "core/intersect.h"
#include "core/math.h"
#include "core/traverse.h"

namespace raynode::core {

/// Higham's gamma(n) = n u / (1 - n u) with the unit roundoff u = 2^-24:
/// a bound on the relative error of n chained float operations.
constexpr float gamma_bound(int n) { return (float(n) * 0x1p-24f) / (1.0f - float(n) * 0x1p-24f); }

/// The next float above `v` (+inf stays); -0 and +0 both go to the smallest
/// positive subnormal. Exact bit arithmetic, no rounding mode involved.
inline float next_float_up(float v) {
  if (std::isinf(v) && v > 0.0f) return v;
  if (v == 0.0f) v = 0.0f;  // -0 -> +0
  std::uint32_t bits = std::bit_cast<std::uint32_t>(v);
  bits = v >= 0.0f ? bits + 1 : bits - 1;
  return std::bit_cast<float>(bits);
}

/// The next float below `v` (-inf stays); mirror of next_float_up.
inline float next_float_down(float v) { return -next_float_up(-v); }

/// A point on a surface and the absolute error bound of each of its
/// coordinates, in world units: the exact surface point the hit stands for
/// lies within [p - error, p + error]; and the surface's unit geometric
/// normal there, unflipped (geometric_normal's orientation), zero where it
/// is undefined. hit_point takes a sphere's or cone's normal from the point
/// in double before its rounding to `p`: far from the origin, p's rounding
/// (a float spacing of its coordinates) is a sizeable part of a small
/// radius, and a normal from p would tilt by it.
struct HitPoint {
  Vec3 p;
  Vec3 error;
  Vec3 normal;
};

/// The point where `ray` crosses the plane of the triangle `prim`, o + t d
/// with t from triangle_plane_t, computed in double and rounded once, and
/// its error bound: that rounding plus |d| times t's bound.
inline HitPoint ray_hit_point(const Primitive& prim, const Ray& ray) {
  HitPoint h;  // its normal is left to the caller (a triangle's is the plane's)
  double t = 0, err = 0;
  if (!triangle_plane_t(ray, prim.vertex(0), prim.vertex(1), prim.vertex(2), t, err)) {
    h.error = {kInfinity, kInfinity, kInfinity};
    return h;
  }
  for (int i = 0; i < 3; ++i) {
    const double o = ray.origin[i], td = t * ray.direction[i];
    h.p[i] = float(o + td);
    h.error[i] = float(std::fabs(double(h.p[i])) * 0x1p-23 + std::fabs(double(ray.direction[i])) * err +
                       (std::fabs(o) + std::fabs(td)) * 0x1p-50);
  }
  return h;
}

/// The point of `hit` (a hit of `ray` on `prim`) and its error bound.
/// Triangles: from the barycentrics, p = b0 v0 + b1 v1 + b2 v2, error
/// gamma(7) sum |b_i v_i| (pbrt-v4, Triangle::InteractionFromIntersection):
/// it depends on the vertices' magnitudes, not on the ray's length; or, when
/// its bound is smaller, the ray's point (ray_hit_point).
/// Spheres and cones: ray.at(t) reprojected onto the surface in double
/// precision (pbrt-v4 reprojects spheres and cylinders the same way), so
/// only the final rounding to float remains: gamma(2) |p| plus the double
/// computation's error relative to the primitive's own magnitudes.
/// Pure; never throws. The error is finite when the primitive is.
inline HitPoint hit_point(const Primitive& prim, const Ray& ray, const Hit& hit) {
  HitPoint h;
  switch (prim.kind) {
    case PrimitiveKind::kTriangle: {
      const float b1 = hit.u, b2 = hit.v, b0 = 1.0f - b1 - b2;
      const Vec3 a = prim.vertex(0) * b0, b = prim.vertex(1) * b1, c = prim.vertex(2) * b2;
      h.p = a + b + c;
      h.error = (abs(a) + abs(b) + abs(c)) * gamma_bound(7);
      h.normal = geometric_normal(prim, h.p);  // the plane's, wherever the point
      // On a triangle far larger than the distance to the hit (a 1e8 ground
      // seen from 1e-2 away) the barycentric point errs by the vertices'
      // float spacing; the ray's point o + t d is then the better one.
      HitPoint r = ray_hit_point(prim, ray);
      if (r.error.x + r.error.y + r.error.z < h.error.x + h.error.y + h.error.z) {
        r.normal = h.normal;
        return r;
      }
      return h;
    }
    case PrimitiveKind::kSphere: {
      const double c[3] = {prim.data[0], prim.data[1], prim.data[2]};
      const double r = std::fabs(double(prim.radius()));
      double q[3];
      for (int i = 0; i < 3; ++i) q[i] = double(ray.origin[i]) + double(hit.t) * ray.direction[i] - c[i];
      const double len = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
      const double s = len > 0.0 ? r / len : 1.0;
      double mag = r;
      for (int i = 0; i < 3; ++i) {
        h.p[i] = float(c[i] + q[i] * s);
        mag = std::max(mag, std::fabs(c[i]));
      }
      h.error = abs(h.p) * gamma_bound(2) + Vec3{1.0f, 1.0f, 1.0f} * float(mag * 0x1p-40);
      h.normal = len > 0.0 ? unit_from_double(q) : geometric_normal(prim, h.p);
      return h;
    }
    case PrimitiveKind::kCone: {
      const double b[3] = {prim.data[0], prim.data[1], prim.data[2]};
      double w[3] = {double(prim.data[4]) - b[0], double(prim.data[5]) - b[1], double(prim.data[6]) - b[2]};
      const double hgt = std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
      const double rb = std::fabs(double(prim.cone_base_radius())), ra = std::fabs(double(prim.cone_apex_radius()));
      double q[3];
      for (int i = 0; i < 3; ++i) q[i] = double(ray.origin[i]) + double(hit.t) * ray.direction[i] - b[i];
      double mag = std::max(hgt, std::max(ra, rb));
      bool has_normal = false;
      if (hgt > 0.0) {
        for (double& x : w) x /= hgt;
        const double s = q[0] * w[0] + q[1] * w[1] + q[2] * w[2];  // axial position
        double perp[3];
        for (int i = 0; i < 3; ++i) perp[i] = q[i] - s * w[i];
        const double len = std::sqrt(perp[0] * perp[0] + perp[1] * perp[1] + perp[2] * perp[2]);
        const double k = (ra - rb) / hgt;
        const double radius = rb + k * s;  // the surface's radius there
        if (len > 0.0 && radius >= 0.0) {
          for (int i = 0; i < 3; ++i) q[i] = s * w[i] + perp[i] * (radius / len);
          // geometric_normal's gradient at the reprojected point: its
          // perpendicular part (radius long) minus the axis times radius * k.
          double n[3];
          for (int i = 0; i < 3; ++i) n[i] = perp[i] * (radius / len) - w[i] * (radius * k);
          h.normal = unit_from_double(n);
          has_normal = true;
        }
      }
      for (int i = 0; i < 3; ++i) {
        h.p[i] = float(b[i] + q[i]);
        mag = std::max(mag, std::fabs(b[i]));
      }
      h.error = abs(h.p) * gamma_bound(2) + Vec3{1.0f, 1.0f, 1.0f} * float(mag * 0x1p-40);
      if (!has_normal) h.normal = geometric_normal(prim, h.p);
      return h;
    }
  }
  h.p = ray.at(hit.t);
  h.error = abs(h.p) * gamma_bound(4);
  h.normal = geometric_normal(prim, h.p);
  return h;
}

/// Origin for a ray that leaves the surface at `hit` on the side of the unit
/// normal `n`: p moved along n by the error bound projected on n, then each
/// moved coordinate rounded one float further away, so that the origin lies
/// strictly on n's side of the exact surface (pbrt-v4, OffsetRayOrigin). The
/// offset is a few float spacings of the vertices' magnitudes: nothing the
/// scene's size or position can make too small or too large.
inline Vec3 offset_ray_origin(const HitPoint& hit, const Vec3& n) {
  const float d = dot(abs(n), hit.error);
  const Vec3 offset = n * d;
  Vec3 o = hit.p + offset;
  for (int i = 0; i < 3; ++i) {
    if (offset[i] > 0.0f) o[i] = next_float_up(o[i]);
    else if (offset[i] < 0.0f) o[i] = next_float_down(o[i]);
  }
  return o;
}

}  // namespace raynode::core
