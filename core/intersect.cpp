#include "core/intersect.h"

namespace raynode::core {

Vec3 unit_from_double(const double a[3]) {
  const double len = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
  if (!(len > 0.0) || !std::isfinite(len)) return {0, 0, 0};
  return {float(a[0] / len), float(a[1] / len), float(a[2] / len)};
}

Vec3 geometric_normal(const Primitive& p, const Vec3& x) {
  switch (p.kind) {
    case PrimitiveKind::kTriangle: {
      // In double: the products of float edges are exact there, and neither
      // they nor the squared length overflow (edges of 1e10 and beyond would
      // in float).
      return unit_from_double(triangle_frame_double(p.vertex(0), p.vertex(1), p.vertex(2)).n);
    }
    case PrimitiveKind::kSphere: {
      const double n[3] = {double(x.x) - p.data[0], double(x.y) - p.data[1], double(x.z) - p.data[2]};
      return unit_from_double(n);
    }
    case PrimitiveKind::kCone: {
      // Gradient of |q_perp|^2 - r(s)^2 in the cone's frame, in double.
      double w[3], q[3];
      for (int i = 0; i < 3; ++i) {
        w[i] = double(p.data[4 + i]) - p.data[i];
        q[i] = double(x[i]) - p.data[i];
      }
      const double h = std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
      if (!(h > 0.0)) return {0, 0, 0};
      for (double& c : w) c /= h;
      const double s = q[0] * w[0] + q[1] * w[1] + q[2] * w[2];
      const double rb = std::fabs(double(p.cone_base_radius())), ra = std::fabs(double(p.cone_apex_radius()));
      const double k = (ra - rb) / h;
      const double r = rb + k * s;
      double n[3];
      for (int i = 0; i < 3; ++i) n[i] = (q[i] - w[i] * s) - w[i] * (r * k);
      return unit_from_double(n);
    }
  }
  return {0, 0, 1};
}

}  // namespace raynode::core
