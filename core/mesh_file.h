// Mesh files through Assimp: OBJ (+MTL), PLY, STL, OFF, glTF 2.0 / GLB and
// every other format the installed Assimp imports, read into the same Scene
// an NFF file gives (triangles as `p`, or `pp` when the file has vertex
// normals), so that every mode, the grid and the pager see no difference.
//
// Place in the data flow: load_scene (scene_source.h) -> read_mesh -> Scene.
// Only core/mesh_file.cpp includes Assimp. The rules (materials, defaults
// for missing lights and view, what is dropped) are in docs/meshes.md.
#pragma once

#include <string>
#include <vector>

#include "core/scene.h"
#include "core/scene_view.h"

namespace raynode::core {

/// True when `path`'s extension names a format Assimp imports and NFF does
/// not claim (`.nff`, `.gz` stay NFF), case-insensitive: `.obj`, `.ply`,
/// `.stl`, `.off`, `.gltf`, `.glb`, ...
bool is_mesh_extension(const std::string& path);

/// True when the first bytes of `data` say a mesh format Assimp can tell by
/// content: `ply` (PLY), `OFF` (OFF), `glTF` (GLB), `solid ` (ASCII STL).
bool has_mesh_magic(const std::string& data);

/// True when `path` is read as a mesh: is_mesh_extension, or a regular file
/// with another extension whose first bytes pass has_mesh_magic.
bool is_mesh_file(const std::string& path);

/// Reads the mesh at `path`. Polygons are triangulated, node transforms
/// applied, coordinates otherwise kept. Each triangle becomes a `pp` patch
/// with the file's vertex normals when the mesh has them (normalised; a zero
/// or non-finite normal makes the triangle flat), else a `p` polygon;
/// degenerate triangles are dropped and counted (Scene::dropped_degenerate).
/// Points and lines are skipped. Materials map to NFF's as docs/meshes.md
/// says; a file without materials, lights or a camera gets defaults.
/// `notes` (may be null) receives one line per default filled in or thing
/// skipped, each naming the file ("bunny.ply has no view: framing its
/// bounding box from +z").
/// `view` (--eye, --at, --up, --fov) is applied to the file's or the framed
/// view before default lights are placed, so that they stand beside the eye
/// it gives; with both eye and at given, no framing is reported.
/// Throws std::runtime_error naming the file ("cannot read mesh 'x.ply':
/// <Assimp's reason>") when Assimp cannot import it or it holds no
/// triangles or a non-finite coordinate; std::invalid_argument for an
/// unusable `view` (apply_view_override); StopError when a stop is requested.
Scene read_mesh(const std::string& path, std::vector<std::string>* notes = nullptr, const ViewOverride& view = {});

}  // namespace raynode::core
