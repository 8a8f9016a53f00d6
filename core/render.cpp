#include "core/render.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/scene_view.h"

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
  return default_view(db.bounds, db.view);
}

RenderResult render(const Database& db, const Grid& grid, const RenderParams& params) {
  return render_image(DirectView(db, grid), db, params);
}

RAYNODE_TRACER_INSTANCES(, DirectView);

}  // namespace raynode::core
