// A uniform scale and a translation of a whole scene: geometry, lights and
// view together, so that the picture stays the same.
//
// Place in the data flow: load_scene (scene_source.h, --scale/--translate)
// or a test -> transform_scene -> Scene -> make_database. Used to check that
// the tracer is scale- and position-invariant (tests/robustness) and to let
// users reproduce a scene at another size or place.
#pragma once

#include <array>

#include "core/scene.h"

namespace raynode::core {

/// x -> scale * x + translate, applied to every point of a scene.
struct SceneTransform {
  double scale = 1.0;                          ///< dimensionless, finite, > 0
  std::array<double, 3> translate{0, 0, 0};    ///< world units, finite
  bool is_identity() const { return scale == 1.0 && translate == std::array<double, 3>{0, 0, 0}; }
};

/// Applies `t` to `scene` in place: polygon and patch vertices, sphere
/// centres and radii, cone ends and radii, light positions, the view's
/// 'from', 'at' and hither distance (scaled; 'up', the angle and the patch
/// normals keep their directions). Each coordinate is computed in double
/// and rounded once to float. Throws std::invalid_argument when the scale
/// is not finite and positive, a translation is not finite, or a result
/// does not fit in a float (the message names the first such value).
void transform_scene(Scene& scene, const SceneTransform& t);

/// Throws what transform_scene(scene, t) would throw, and changes nothing.
void check_transform(const Scene& scene, const SceneTransform& t);

/// The translation that moves `scene` so that its eye (the view's 'from';
/// the centre of its bounds when it has no view) lies at the origin: the
/// space the rendering commands trace in (pbrt-v4's "camera-world" rendering
/// space). The tracer's arithmetic then runs at the scene's own magnitudes
/// wherever the scene lies: a float point or ray origin a thousand units
/// from the origin carries 1/16 000 of a unit of rounding, one beside the
/// eye far less, and a picture of many refractions differed on 2% of its
/// pixels for it. The differences are exact for coordinates within a
/// factor of two of the eye's (Sterbenz), so the scene's shape is kept.
/// Identity when some coordinate minus the eye's would not fit in a float.
SceneTransform eye_at_origin(const Scene& scene);

/// `t` followed by eye_at_origin's translation of the transformed scene, as
/// one transform: x -> scale (x - eye), the eye taken in `scene`'s own
/// coordinates, so that `t`'s translation cancels exactly and every
/// coordinate is rounded to float once. A scene moved with --translate
/// thus renders exactly as where it was (only its file's own rounding, as
/// `scene write --translate` leaves it, can change a moved picture), and a
/// scaled one is rounded once, at the scale. Throws what
/// transform_scene(scene, t) would throw.
SceneTransform eye_at_origin_after(const Scene& scene, const SceneTransform& t);

/// Appends a "stadium" floor to `scene`: one square polygon, `factor` times
/// the scene's largest extent on a side, centred under the scene's bounds,
/// normal to the world axis nearest the view's up, a hundredth of that
/// extent below the bounds (along -up), in a diffuse grey material of its
/// own. The grid benchmarks' "small object in a huge scene" (a mesh on a
/// floor 100x or 1000x its size). Lights and view are kept. Throws
/// std::invalid_argument when `factor` is not in [1, 1e6], the scene has no
/// primitive, or a corner does not fit in a float.
void add_stadium_floor(Scene& scene, double factor);

}  // namespace raynode::core
