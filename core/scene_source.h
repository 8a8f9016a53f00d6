// Where a scene comes from: an NFF file or a built-in SPD generator.
//
// Place in the data flow: the SCENE argument of every raynode subcommand ->
// load_scene -> Scene. A spec naming an existing file that is not a
// directory (a FIFO or a device too), containing a '/', or ending in `.nff`
// or `.nff.gz`, is read as NFF; anything else is parsed as `name[:size]` of a
// built-in generator (spd.h).
#pragma once

#include <string>
#include <utility>

#include "core/scene.h"
#include "core/scene_transform.h"

namespace raynode::core {

struct SceneSource {
  SceneSource() = default;
  SceneSource(std::string spec_, int tessellate_ = 0, const SceneTransform& transform_ = {})
      : spec(std::move(spec_)), tessellate(tessellate_), transform(transform_) {}

  std::string spec;    ///< path or name[:size]
  int tessellate = 0;  ///< --tessellate R (0 = keep curved primitives)
  SceneTransform transform;  ///< --scale / --translate, applied after tessellation
};

/// True if `spec` will be read as a file.
bool is_scene_file(const std::string& spec);

/// Loads the scene, tessellates it, then applies `transform`
/// (transform_scene). Throws ParseError (malformed file, with file:line:col),
/// std::runtime_error (unreadable file, more than the memory limit:
/// scene_file.h), std::invalid_argument (unknown generator, bad size, bad
/// tessellation) or StopError (a stop was requested while reading, parsing
/// or tessellating: core/stop.h).
Scene load_scene(const SceneSource& source);

}  // namespace raynode::core
