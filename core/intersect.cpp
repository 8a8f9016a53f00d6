#include "core/intersect.h"

namespace raynode::core {

Vec3 geometric_normal(const Primitive& p, const Vec3& x) {
  switch (p.kind) {
    case PrimitiveKind::kTriangle:
      return cross(p.vertex(1) - p.vertex(0), p.vertex(2) - p.vertex(0));
    case PrimitiveKind::kSphere:
      return x - p.center();
    case PrimitiveKind::kCone: {
      // Gradient of |q_perp|^2 - r(s)^2 in the cone's frame.
      const Vec3 axis = p.cone_apex() - p.cone_base();
      const float h = length(axis);
      const Vec3 w = axis * (1.0f / h);
      const Vec3 q = x - p.cone_base();
      const float s = dot(q, w);
      const Vec3 perp = q - w * s;
      const float k = (std::fabs(p.cone_apex_radius()) - std::fabs(p.cone_base_radius())) / h;
      const float r = std::fabs(p.cone_base_radius()) + k * s;
      return perp - w * (r * k);
    }
  }
  return {0, 0, 1};
}

}  // namespace raynode::core
