#include "core/scene_transform.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace raynode::core {

namespace {

void check_parameters(const SceneTransform& t) {
  if (!(std::isfinite(t.scale) && t.scale > 0.0))
    throw std::invalid_argument(fmt::format("scale must be finite and positive, got {}", t.scale));
  for (double x : t.translate)
    if (!std::isfinite(x)) throw std::invalid_argument(fmt::format("translation must be finite, got {}", x));
}

/// Maps every point and length of `scene` by `t`, each computed in double
/// and rounded once (kApply), or only checks that every result fits in a
/// float; throws std::invalid_argument naming the first that does not.
template <bool kApply, class SceneT>
void map_scene(SceneT& scene, const SceneTransform& t) {
  auto length = [&](auto& v, const char* what) {
    const double r = double(v) * t.scale;
    if (!(std::fabs(r) <= double(std::numeric_limits<float>::max())))
      throw std::invalid_argument(fmt::format("{} {} scaled by {} does not fit in a float", what, v, t.scale));
    if constexpr (kApply) v = float(r);
  };
  auto point = [&](auto& p, const char* what) {
    for (int a = 0; a < 3; ++a) {
      const double r = double(p[a]) * t.scale + t.translate[std::size_t(a)];
      if (!(std::fabs(r) <= double(std::numeric_limits<float>::max())))
        throw std::invalid_argument(fmt::format("{} ({}, {}, {}) transformed does not fit in a float", what, p.x,
                                                p.y, p.z));
      if constexpr (kApply) p[a] = float(r);
    }
  };
  for (auto& v : scene.vertices) point(v, "vertex");
  for (auto& s : scene.spheres) {
    point(s.center, "sphere centre");
    length(s.radius, "sphere radius");
  }
  for (auto& c : scene.cones) {
    point(c.base, "cone base");
    point(c.apex, "cone apex");
    length(c.base_radius, "cone base radius");
    length(c.apex_radius, "cone apex radius");
  }
  for (auto& l : scene.lights) point(l.position, "light");
  point(scene.view.from, "view 'from'");
  point(scene.view.at, "view 'at'");
  length(scene.view.hither, "view 'hither'");
}

/// The eye of the rendering space: the view's 'from', or the centre of the
/// bounds without a view; false for a scene without either.
bool rendering_eye(const Scene& scene, Vec3& eye) {
  eye = scene.view.from;
  if (scene.has_view) return true;
  const Bounds3 b = scene.bounds();
  if (b.empty()) return false;
  for (int a = 0; a < 3; ++a) eye[a] = float(0.5 * (double(b.lower[a]) + double(b.upper[a])));
  return true;
}

/// True when `eye` is finite and every point of `scene` minus it fits in a
/// float.
bool differences_fit(const Scene& scene, const Vec3& eye) {
  if (!(std::isfinite(eye.x) && std::isfinite(eye.y) && std::isfinite(eye.z))) return false;
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
  return fits;
}

}  // namespace

void transform_scene(Scene& scene, const SceneTransform& t) {
  check_parameters(t);
  if (t.is_identity()) return;
  map_scene<true>(scene, t);
}

void check_transform(const Scene& scene, const SceneTransform& t) {
  check_parameters(t);
  if (!t.is_identity()) map_scene<false>(scene, t);
}

SceneTransform eye_at_origin_after(const Scene& scene, const SceneTransform& t) {
  check_transform(scene, t);
  Vec3 eye;
  const bool has_eye = rendering_eye(scene, eye);
  if (has_eye && !differences_fit(scene, eye)) {
    if (t.is_identity()) return t;  // left where it is, as eye_at_origin leaves it
    // The eye's differences do not fit in float before the transform: take
    // them after it, as the rendering space of the transformed scene.
    Scene moved = scene;
    transform_scene(moved, t);
    const SceneTransform after = eye_at_origin(moved);
    SceneTransform c = t;
    for (std::size_t a = 0; a < 3; ++a) c.translate[a] = t.translate[a] + after.translate[a];
    return c;
  }
  // x -> scale x + translate - (scale eye + translate) = scale (x - eye):
  // the translation cancels exactly.
  SceneTransform c;
  c.scale = t.scale;
  if (has_eye)
    for (std::size_t a = 0; a < 3; ++a) c.translate[a] = -t.scale * double(eye[int(a)]);
  return c;
}

SceneTransform eye_at_origin(const Scene& scene) {
  Vec3 eye;
  if (!rendering_eye(scene, eye) || !differences_fit(scene, eye)) return {};
  SceneTransform t;
  t.translate = {-double(eye.x), -double(eye.y), -double(eye.z)};
  return t;
}

void add_stadium_floor(Scene& scene, double factor) {
  if (!(factor >= 1.0 && factor <= 1e6))
    throw std::invalid_argument(fmt::format("--floor must be between 1 and 1e6, got {}", factor));
  const Bounds3 b = scene.bounds();
  if (b.empty()) throw std::invalid_argument("--floor: the scene has no primitive to put a floor under");
  const Vec3 up = scene.view.up;
  int k = 0;  // the axis nearest the view's up
  for (int a = 1; a < 3; ++a)
    if (std::fabs(up[a]) > std::fabs(up[k])) k = a;
  const int u = (k + 1) % 3, v = (k + 2) % 3;
  const Vec3 e = b.extent();
  const double size = std::max(std::max({double(e.x), double(e.y), double(e.z)}), std::numeric_limits<double>::min());
  const double half = 0.5 * factor * size;
  // Below the bounds along -up: under the lowest point when up points along
  // +axis k, above the highest when along -axis k.
  const double level = up[k] >= 0 ? double(b.lower[k]) - 0.01 * size : double(b.upper[k]) + 0.01 * size;
  const double cu = 0.5 * (double(b.lower[u]) + b.upper[u]), cv = 0.5 * (double(b.lower[v]) + b.upper[v]);
  Vec3 corners[4];  // counter-clockwise seen from the up side
  const double su[4] = {-1, 1, 1, -1}, sv[4] = {-1, -1, 1, 1};
  for (int i = 0; i < 4; ++i) {
    double q[3];
    q[k] = level, q[u] = cu + su[i] * half, q[v] = cv + sv[i] * half;
    for (int a = 0; a < 3; ++a)
      if (!(std::fabs(q[a]) <= double(std::numeric_limits<float>::max())))
        throw std::invalid_argument(fmt::format("--floor {}: a corner of the floor, {}, does not fit in a float",
                                                factor, q[a]));
    corners[up[k] >= 0 ? i : 3 - i] = Vec3{float(q[0]), float(q[1]), float(q[2])};
  }
  Material grey;
  grey.color = Vec3{0.6f, 0.6f, 0.6f};
  grey.kd = 0.8f;
  scene.materials.push_back(grey);
  scene.add_polygon(corners, 4);
}

}  // namespace raynode::core
