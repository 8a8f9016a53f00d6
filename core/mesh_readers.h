// raynode's own readers for PLY and OFF, the two mesh formats whose Assimp
// importers crash on truncated input (Assimp 5.2: a binary PLY shorter than
// its header says reads past the buffer; an OFF file with fewer faces than
// announced aborts on an assertion). A 1M-triangle binary PLY reads, with
// the database built, in about 0.6 s (`raynode scene info`).
//
// Place in the data flow: read_mesh (mesh_file.h) -> read_scene_text (the
// bytes, within the memory limit; gzip inflated) -> read_ply / read_off ->
// MeshData -> the triangles read_mesh adds to the Scene.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "core/math.h"

namespace raynode::core {

/// One mesh as a file gives it: indexed polygons, not yet triangulated.
struct MeshData {
  std::vector<Vec3> positions;               ///< file coordinates
  std::vector<Vec3> normals;                 ///< empty, or one per position (as given, not normalised)
  std::vector<std::uint32_t> face_sizes;     ///< vertices per face (1 = point, 2 = line)
  std::vector<std::uint32_t> face_indices;   ///< face_sizes[i] indices per face, into positions
};

/// Parses a PLY file (ASCII, binary little- or big-endian; header
/// "ply"/"format"/"element"/"property"/"end_header"). Reads the `vertex`
/// element's x, y, z (and nx, ny, nz when all three are present) and the
/// `face` element's `vertex_indices` (or `vertex_index`) list; skips every
/// other element and property. Every index is checked against the vertex
/// count. Throws std::runtime_error "cannot read mesh '<path>': <what, where,
/// the numbers>" on a malformed header, a truncated body, a bad number or
/// an index out of range.
MeshData read_ply(std::string_view bytes, const std::string& path);

/// Parses an OFF file: "OFF" (or "NOFF", with a normal after each vertex;
/// "COFF"/"CNOFF" colours are skipped), the counts "V F E", V vertex lines,
/// F face lines "n i1 .. in [colour]"; `#` starts a comment. Throws
/// std::runtime_error as read_ply does, naming the line.
MeshData read_off(std::string_view bytes, const std::string& path);

}  // namespace raynode::core
