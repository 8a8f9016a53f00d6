#include "core/cell_blocks.h"

#include <fmt/core.h>

#include <limits>
#include <stdexcept>

namespace raynode::core {

CellBlocks build_cell_blocks(const Database& db, const Grid& grid, std::uint32_t min_triangles) {
  if (min_triangles == 0) throw std::invalid_argument("build_cell_blocks: min_triangles must be at least 1");
  CellBlocks out;
  out.min_triangles = min_triangles;
  const std::uint32_t cells = grid.leaf_cells();  // uniform: every cell; adaptive: the leaf cells
  out.start.assign(std::size_t(cells) + 1, 0);
  const auto packed = [&](std::uint32_t c) {
    const std::uint32_t b = grid.cell_start[c], e = grid.cell_start[c + 1];
    if (e - b < min_triangles) return false;
    for (std::uint32_t i = b; i < e; ++i)
      if (db.primitives[grid.cell_primitives[i]].kind != PrimitiveKind::kTriangle) return false;
    return true;
  };
  std::uint64_t total = 0;
  for (std::uint32_t c = 0; c < cells; ++c) {
    out.start[c] = std::uint32_t(total);
    if (packed(c)) total += (grid.cell_start[c + 1] - grid.cell_start[c] + kBlockLanes - 1) / kBlockLanes;
    if (total > std::numeric_limits<std::uint32_t>::max())
      throw std::length_error(fmt::format("build_cell_blocks: more than 2^32 blocks ({} cells)", cells));
  }
  out.start[cells] = std::uint32_t(total);
  out.blocks.assign(total, TriangleBlock{});
  for (std::uint32_t c = 0; c < cells; ++c) {
    if (out.start[c] == out.start[c + 1]) continue;
    TriangleBlock* block = &out.blocks[out.start[c]];
    std::uint32_t lane = 0;
    for (std::uint32_t i = grid.cell_start[c]; i < grid.cell_start[c + 1]; ++i) {
      const std::uint32_t id = grid.cell_primitives[i];
      const Primitive& p = db.primitives[id];
      for (int vtx = 0; vtx < 3; ++vtx)
        for (int a = 0; a < 3; ++a) block->v[vtx][a][lane] = p.data[3 * vtx + a];
      block->primitive[lane] = id;
      if (++lane == kBlockLanes) {
        lane = 0;
        ++block;
      }
    }
  }
  return out;
}

}  // namespace raynode::core
