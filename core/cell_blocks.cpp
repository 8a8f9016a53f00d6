#include "core/cell_blocks.h"

#include <fmt/core.h>

#include <limits>
#include <stdexcept>

namespace raynode::core {

namespace {

// Sets `start` to the block offsets of the cells holding at least `min`
// primitives, all of `kind`, and returns the block count.
std::uint32_t plan_blocks(const Database& db, const Grid& grid, std::uint32_t min, PrimitiveKind kind,
                          std::vector<std::uint32_t>& start) {
  const std::uint32_t cells = grid.leaf_cells();  // uniform: every cell; adaptive: the leaf cells
  start.assign(std::size_t(cells) + 1, 0);
  const auto packed = [&](std::uint32_t c) {
    const std::uint32_t b = grid.cell_start[c], e = grid.cell_start[c + 1];
    if (e - b < min) return false;
    for (std::uint32_t i = b; i < e; ++i)
      if (db.primitives[grid.cell_primitives[i]].kind != kind) return false;
    return true;
  };
  std::uint64_t total = 0;
  for (std::uint32_t c = 0; c < cells; ++c) {
    start[c] = std::uint32_t(total);
    if (packed(c)) total += (grid.cell_start[c + 1] - grid.cell_start[c] + kBlockLanes - 1) / kBlockLanes;
    if (total > std::numeric_limits<std::uint32_t>::max())
      throw std::length_error(fmt::format("build_cell_blocks: more than 2^32 blocks ({} cells)", cells));
  }
  start[cells] = std::uint32_t(total);
  return std::uint32_t(total);
}

// Fills `blocks` (sized by plan_blocks) cell by cell, lane by lane, in list
// order: put(block, lane, id, primitive) writes one lane.
template <class Block, class Put>
void fill_blocks(const Database& db, const Grid& grid, const std::vector<std::uint32_t>& start,
                 std::vector<Block>& blocks, Put&& put) {
  for (std::uint32_t c = 0; c + 1 < start.size(); ++c) {
    if (start[c] == start[c + 1]) continue;
    Block* block = &blocks[start[c]];
    std::uint32_t lane = 0;
    for (std::uint32_t i = grid.cell_start[c]; i < grid.cell_start[c + 1]; ++i) {
      const std::uint32_t id = grid.cell_primitives[i];
      put(*block, lane, id, db.primitives[id]);
      if (++lane == kBlockLanes) {
        lane = 0;
        ++block;
      }
    }
  }
}

}  // namespace

CellBlocks build_cell_blocks(const Database& db, const Grid& grid, std::uint32_t min_triangles, PackKinds kinds) {
  if (min_triangles == 0) throw std::invalid_argument("build_cell_blocks: min_triangles must be at least 1");
  CellBlocks out;
  out.min_triangles = min_triangles;
  out.blocks.assign(plan_blocks(db, grid, min_triangles, PrimitiveKind::kTriangle, out.start), TriangleBlock{});
  fill_blocks(db, grid, out.start, out.blocks,
              [](TriangleBlock& b, std::uint32_t lane, std::uint32_t id, const Primitive& p) {
                for (int vtx = 0; vtx < 3; ++vtx)
                  for (int a = 0; a < 3; ++a) b.v[vtx][a][lane] = p.data[3 * vtx + a];
                b.primitive[lane] = id;
              });
  if (kinds == PackKinds::kTrianglesAndSpheres) {
    std::vector<std::uint32_t> start;
    const std::uint32_t n =
        plan_blocks(db, grid, min_triangles, PrimitiveKind::kSphere, start);
    if (n > 0) {  // otherwise no sphere arrays: the views skip the second look-up
      out.sphere_start = std::move(start);
      out.sphere_blocks.assign(n, SphereBlock{});
      fill_blocks(db, grid, out.sphere_start, out.sphere_blocks,
                  [](SphereBlock& b, std::uint32_t lane, std::uint32_t id, const Primitive& p) {
                    for (int a = 0; a < 3; ++a) b.center[a][lane] = p.data[a];
                    b.radius[lane] = p.radius();
                    b.primitive[lane] = id;
                  });
    }
  }
  return out;
}

}  // namespace raynode::core
