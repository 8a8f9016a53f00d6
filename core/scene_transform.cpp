#include "core/scene_transform.h"

#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <stdexcept>

namespace raynode::core {

void transform_scene(Scene& scene, const SceneTransform& t) {
  if (!(std::isfinite(t.scale) && t.scale > 0.0))
    throw std::invalid_argument(fmt::format("scale must be finite and positive, got {}", t.scale));
  for (double x : t.translate)
    if (!std::isfinite(x)) throw std::invalid_argument(fmt::format("translation must be finite, got {}", x));
  if (t.is_identity()) return;
  auto length = [&](float v, const char* what) {
    const double r = double(v) * t.scale;
    if (!(std::fabs(r) <= double(std::numeric_limits<float>::max())))
      throw std::invalid_argument(fmt::format("{} {} scaled by {} does not fit in a float", what, v, t.scale));
    return float(r);
  };
  auto point = [&](Vec3& p, const char* what) {
    for (int a = 0; a < 3; ++a) {
      const double r = double(p[a]) * t.scale + t.translate[std::size_t(a)];
      if (!(std::fabs(r) <= double(std::numeric_limits<float>::max())))
        throw std::invalid_argument(fmt::format("{} ({}, {}, {}) transformed does not fit in a float", what, p.x,
                                                p.y, p.z));
      p[a] = float(r);
    }
  };
  for (Vec3& v : scene.vertices) point(v, "vertex");
  for (Sphere& s : scene.spheres) {
    point(s.center, "sphere centre");
    s.radius = length(s.radius, "sphere radius");
  }
  for (Cone& c : scene.cones) {
    point(c.base, "cone base");
    point(c.apex, "cone apex");
    c.base_radius = length(c.base_radius, "cone base radius");
    c.apex_radius = length(c.apex_radius, "cone apex radius");
  }
  for (Light& l : scene.lights) point(l.position, "light");
  point(scene.view.from, "view 'from'");
  point(scene.view.at, "view 'at'");
  scene.view.hither = length(scene.view.hither, "view 'hither'");
}

SceneTransform eye_at_origin(const Scene& scene) {
  Vec3 eye = scene.view.from;
  if (!scene.has_view) {
    const Bounds3 b = scene.bounds();
    if (b.empty()) return {};
    for (int a = 0; a < 3; ++a) eye[a] = float(0.5 * (double(b.lower[a]) + double(b.upper[a])));
  }
  bool fits = true;
  auto check = [&](const Vec3& p) {
    for (int a = 0; a < 3; ++a) fits &= std::fabs(double(p[a]) - double(eye[a])) <= double(std::numeric_limits<float>::max());
  };
  for (const Vec3& v : scene.vertices) check(v);
  for (const Sphere& s : scene.spheres) check(s.center);
  for (const Cone& c : scene.cones) {
    check(c.base);
    check(c.apex);
  }
  for (const Light& l : scene.lights) check(l.position);
  check(scene.view.from);
  check(scene.view.at);
  if (!fits || !(std::isfinite(eye.x) && std::isfinite(eye.y) && std::isfinite(eye.z))) return {};
  SceneTransform t;
  t.translate = {-double(eye.x), -double(eye.y), -double(eye.z)};
  return t;
}

}  // namespace raynode::core
