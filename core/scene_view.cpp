// Default, framed and overridden views. See scene_view.h.
#include "core/scene_view.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/camera.h"

namespace raynode::core {

namespace {

std::string text(const Vec3& p) { return fmt::format("({}, {}, {})", p.x, p.y, p.z); }

}  // namespace

View default_view(const Bounds3& bounds, View view) {
  view.at = bounds.empty() ? Vec3{0, 0, 0} : bounds.center();
  float size = bounds.empty() ? 1.0f : length(bounds.extent());
  if (!std::isfinite(size)) size = float(length_double(bounds.extent()));  // |extent|^2 overflows float
  // The camera stands back 1.5 scene diagonals, and at least 2^-12 of the
  // centre's largest coordinate: the offset must survive rounding where the
  // scene lies. A scene smaller than the float spacing at its centre (a
  // 0.07-radius sphere at x = 6.5e6, where floats are 0.5 apart) would
  // otherwise leave 'from' on 'at' in x and y, and the viewing direction
  // parallel to 'up'. At 2^-12 each offset component spans at least ~2^9
  // float spacings, so the direction is off by under 0.2%.
  const float reach = std::max({std::fabs(view.at.x), std::fabs(view.at.y), std::fabs(view.at.z)});
  const float distance = std::max(1.5f * (size > 0.0f ? size : 1.0f), reach * 0x1p-12f);
  view.from = view.at + Vec3{0.3f, -0.4f, 0.866f} * distance;
  view.up = {0, 0, 1};
  if (!is_finite(view.from))  // extent beyond float range: no camera position can be computed
    throw std::runtime_error(fmt::format("the scene has no view and reaches too far for a default camera (bounds "
                                         "({}, {}, {}) to ({}, {}, {})); give it a 'v' block",
                                         bounds.lower.x, bounds.lower.y, bounds.lower.z, bounds.upper.x,
                                         bounds.upper.y, bounds.upper.z));
  return view;
}

View frame_bounds(const Bounds3& bounds) {
  const Bounds3 b = bounds.empty() ? Bounds3{{0, 0, 0}, {1, 1, 1}} : bounds;
  View v;
  v.angle = 45.0f;
  v.width = v.height = 512;
  v.up = {0, 1, 0};
  v.at = b.center();
  const double radius = 0.5 * length_double(b.extent());
  const float reach = std::max({std::fabs(v.at.x), std::fabs(v.at.y), std::fabs(v.at.z)});
  const double half = 22.5 * 3.14159265358979323846 / 180.0;
  double distance = radius / std::sin(half);
  distance = std::max({distance, double(reach) * 1e-3, 1e-6});
  v.from = v.at + Vec3{0.0f, 0.0f, float(distance)};
  if (!is_finite(v.from))
    throw std::runtime_error(fmt::format("the mesh reaches too far to frame (bounds {} to {}); give a view with "
                                         "--eye, --at, --up, --fov",
                                         text(b.lower), text(b.upper)));
  return v;
}

std::string view_problem(const View& v) {
  if (!is_finite(v.from)) return fmt::format("'from' {} is not finite", text(v.from));
  if (!is_finite(v.at)) return fmt::format("'at' {} is not finite", text(v.at));
  const Vec3 dir = v.at - v.from;
  if (!is_finite(dir))
    return fmt::format("'at' {} is too far from 'from' {}: the viewing direction overflows float", text(v.at),
                       text(v.from));
  if (!(dot(dir, dir) > 0.0f))
    return v.at == v.from ? fmt::format("'at' {} is the same point as 'from'", text(v.at))
                          : fmt::format("'at' {} is too close to 'from' {} to give a viewing direction", text(v.at),
                                        text(v.from));
  if (!up_is_usable(normalize_any(dir), v.up))
    return fmt::format("'up' {} is parallel to the viewing direction {}", text(v.up), text(dir));
  if (!(v.angle > 0.0f && v.angle < 180.0f))
    return fmt::format("field of view {} must be in (0, 180) degrees", v.angle);
  return {};
}

void apply_view_override(Scene& scene, const ViewOverride& o) {
  if (!o.any()) return;
  View v = scene.has_view ? scene.view : default_view(scene.bounds(), scene.view);
  if (o.eye) v.from = *o.eye;
  if (o.at) v.at = *o.at;
  if (o.up) v.up = *o.up;
  if (o.fov) v.angle = *o.fov;
  const std::string problem = view_problem(v);
  if (!problem.empty()) {
    std::string given;
    for (const auto& [name, on] : {std::pair{"--eye", bool(o.eye)}, std::pair{"--at", bool(o.at)},
                                   std::pair{"--up", bool(o.up)}, std::pair{"--fov", bool(o.fov)}})
      if (on) given += (given.empty() ? "" : ", ") + std::string(name);
    throw std::invalid_argument(fmt::format("the view with {} cannot be used: {}", given, problem));
  }
  scene.view = v;
  scene.has_view = true;
}

void fit_resolution(int& width, int& height, const View& view, int max_side) {
  if ((width > 0) == (height > 0)) return;
  const double aspect = double(view.height) / double(view.width);  // NFF resolutions are >= 1
  auto side = [&](double x) { return int(std::clamp(std::lround(x), 1L, long(max_side))); };
  if (width > 0) height = side(width * aspect);
  else width = side(height / aspect);
}

}  // namespace raynode::core
