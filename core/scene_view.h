// Views a scene did not bring: the default camera for a scene without a `v`
// block, the framing of a mesh's bounding box, command-line overrides of the
// view (--eye, --at, --up, --fov) and the resolution when only one of
// --width and --height is given.
//
// Place in the data flow: load_scene (scene_source.h) applies a ViewOverride
// to the Scene before its --scale/--translate; render_view (render.h) uses
// default_view for a scene without a view; apps fill a missing image side
// with fit_resolution. docs/meshes.md ("Camera options") describes the rules.
#pragma once

#include <optional>
#include <string>

#include "core/math.h"
#include "core/scene.h"

namespace raynode::core {

/// Parts of the view given on the command line; the rest comes from the
/// scene's view (or its default view). World units of the scene file, i.e.
/// before --scale and --translate; `fov` is NFF's `angle`, degrees.
struct ViewOverride {
  std::optional<Vec3> eye;   ///< --eye: the view's `from`
  std::optional<Vec3> at;    ///< --at
  std::optional<Vec3> up;    ///< --up
  std::optional<float> fov;  ///< --fov: full field of view, degrees
  /// True when any part is given.
  bool any() const { return eye || at || up || fov; }
};

/// The camera render_view gives a scene without a view: looking at the
/// centre of `bounds` from 1.5 diagonals along (0.3, -0.4, 0.866), up +z,
/// the other fields (angle, resolution) from `base`. Throws
/// std::runtime_error when the bounds reach beyond what float can place.
View default_view(const Bounds3& bounds, View base = {});

/// A view framing `bounds` from +z: looking down -z at the box centre, up
/// +y, `angle` 45 degrees, stood back so that the box's bounding sphere fits
/// the field of view (distance = radius / sin(22.5 degrees), at least 1e-3
/// of the largest coordinate), 512x512 pixels. An empty box frames the unit
/// cube at the origin.
View frame_bounds(const Bounds3& bounds);

/// Why `view` cannot be used by the camera (from == at, up parallel to the
/// viewing direction, angle outside (0, 180), non-finite numbers), in words
/// naming the values; empty when it can. The NFF reader's conditions.
std::string view_problem(const View& view);

/// Applies `override` to `scene`'s view (starting from default_view when the
/// scene has none) and marks the scene as having a view. No-op when nothing
/// is given. Throws std::invalid_argument ("--eye/--at/--up/--fov: ...")
/// when the resulting view is unusable (view_problem).
void apply_view_override(Scene& scene, const ViewOverride& override);

/// Fills a missing side (0) of the image from the view's aspect ratio:
/// `--width 64` on a 512x256 view gives 64x32 (rounded, at least 1 pixel,
/// at most `max_side`). Both given or both missing: unchanged.
void fit_resolution(int& width, int& height, const View& view, int max_side = 16384);

}  // namespace raynode::core
