// Where a scene comes from: an NFF file, a mesh file or a built-in SPD
// generator.
//
// Place in the data flow: the SCENE argument of every raynode subcommand ->
// load_scene -> Scene. A spec naming an existing file that is not a
// directory (a FIFO or a device too), containing a '/', or ending in `.nff`,
// `.nff.gz` or a mesh extension, is a file: a mesh (mesh_file.h: OBJ, PLY, STL, OFF, glTF, ...
// by extension, or by its first bytes) or else NFF; anything else is parsed
// as `name[:size]` of a built-in generator (spd.h).
#pragma once

#include <string>
#include <utility>

#include "core/scene.h"
#include "core/scene_transform.h"
#include "core/scene_view.h"

namespace raynode::core {

struct SceneSource {
  SceneSource() = default;
  SceneSource(std::string spec_, int tessellate_ = 0, const SceneTransform& transform_ = {})
      : spec(std::move(spec_)), tessellate(tessellate_), transform(transform_) {}

  std::string spec;    ///< path or name[:size]
  int tessellate = 0;  ///< --tessellate R (0 = keep curved primitives)
  SceneTransform transform;  ///< --scale / --translate, applied after tessellation
  ViewOverride view;         ///< --eye / --at / --up / --fov, applied before `transform`
  /// --floor K: a stadium floor K times the scene's width under it
  /// (add_stadium_floor, after `view`, before `transform`); 0 = none.
  double floor = 0;
  /// Then move the scene so that its eye lies at the origin (eye_at_origin,
  /// scene_transform.h): the rendering commands' space, composed with
  /// `transform` and rounded once (eye_at_origin_after). Off for the
  /// commands that show or write the scene's own coordinates.
  bool eye_origin = false;
};

/// True if `spec` will be read as a file.
bool is_scene_file(const std::string& spec);

/// Loads the scene, tessellates it, applies the view override
/// (apply_view_override), adds the floor (add_stadium_floor), then `transform` (transform_scene), or, with
/// `eye_origin`, `transform` and eye_at_origin's translation as one
/// (eye_at_origin_after). A mesh's notes
/// (defaults filled in, things skipped: mesh_file.h) go to stderr, one line
/// each, prefixed "raynode: ". Throws ParseError (malformed file, with file:line:col),
/// std::runtime_error (unreadable file, more than the memory limit:
/// scene_file.h), std::invalid_argument (unknown generator, bad size, bad
/// tessellation, an unusable view override), std::runtime_error naming the
/// file for a mesh Assimp cannot read, or StopError (a stop was requested while reading, parsing
/// or tessellating: core/stop.h).
Scene load_scene(const SceneSource& source);

}  // namespace raynode::core
