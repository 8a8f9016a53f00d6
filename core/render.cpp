#include "core/render.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace raynode::core {

RenderMode parse_render_mode(const std::string& name) {
  if (name == "sequential") return RenderMode::kSequential;
  if (name == "shared") return RenderMode::kShared;
  throw std::invalid_argument("unknown render mode '" + name + "' (expected sequential or shared)");
}

const char* render_mode_name(RenderMode mode) {
  switch (mode) {
    case RenderMode::kSequential: return "sequential";
    case RenderMode::kShared: return "shared";
  }
  return "?";
}

View render_view(const Database& db) {
  if (db.has_view) return db.view;
  View view = db.view;
  view.at = db.bounds.empty() ? Vec3{0, 0, 0} : db.bounds.center();
  float size = db.bounds.empty() ? 1.0f : length(db.bounds.extent());
  if (!std::isfinite(size)) size = float(length_double(db.bounds.extent()));  // |extent|^2 overflows float
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
                                         db.bounds.lower.x, db.bounds.lower.y, db.bounds.lower.z, db.bounds.upper.x,
                                         db.bounds.upper.y, db.bounds.upper.z));
  return view;
}

RenderResult render(const Database& db, const Grid& grid, const RenderParams& params) {
  return render_image(DirectView(db, grid), db, params);
}

}  // namespace raynode::core
