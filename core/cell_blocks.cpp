#include "core/cell_blocks.h"

#include <fmt/core.h>

#include <algorithm>
#include <limits>
#include <stdexcept>

namespace raynode::core {

namespace {

// Packed sphere blocks are capped at this many times the blocks that would
// hold each sphere once (chosen with `raynode bench accel`).
constexpr std::uint64_t kSphereBlockBudget = 4;

// Sets `start` to the block offsets of the cells holding at least `min`
// primitives, all of `kind`, and returns the block count. With max_blocks
// > 0, the longest of those cells whose blocks fit in max_blocks.
std::uint32_t plan_blocks(const Database& db, const Grid& grid, std::uint32_t min, PrimitiveKind kind,
                          std::uint64_t max_blocks, std::vector<std::uint32_t>& start) {
  const std::uint32_t cells = grid.leaf_cells();  // uniform: every cell; adaptive: the leaf cells
  start.assign(std::size_t(cells) + 1, 0);
  const auto blocks_of = [&](std::uint32_t c) {
    return (grid.cell_start[c + 1] - grid.cell_start[c] + kBlockLanes - 1) / kBlockLanes;
  };
  const auto packed = [&](std::uint32_t c) {
    const std::uint32_t b = grid.cell_start[c], e = grid.cell_start[c + 1];
    if (e - b < min) return false;
    for (std::uint32_t i = b; i < e; ++i)
      if (db.primitives[grid.cell_primitives[i]].kind != kind) return false;
    return true;
  };
  std::vector<std::uint8_t> chosen(cells, 0);
  for (std::uint32_t c = 0; c < cells; ++c) chosen[c] = packed(c);
  if (max_blocks > 0) {
    // Over budget: the longest cells first (a long list gains the most).
    std::vector<std::uint32_t> order;
    std::uint64_t want = 0;
    for (std::uint32_t c = 0; c < cells; ++c)
      if (chosen[c]) {
        order.push_back(c);
        want += blocks_of(c);
      }
    if (want > max_blocks) {
      std::stable_sort(order.begin(), order.end(),
                       [&](std::uint32_t a, std::uint32_t b) { return blocks_of(a) > blocks_of(b); });
      std::uint64_t taken = 0;
      for (const std::uint32_t c : order) {
        const bool fits = taken + blocks_of(c) <= max_blocks;
        chosen[c] = fits;
        taken += fits ? blocks_of(c) : 0;
      }
    }
  }
  std::uint64_t total = 0;
  for (std::uint32_t c = 0; c < cells; ++c) {
    start[c] = std::uint32_t(total);
    if (chosen[c]) total += blocks_of(c);
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
  out.blocks.assign(plan_blocks(db, grid, min_triangles, PrimitiveKind::kTriangle, 0, out.start), TriangleBlock{});
  fill_blocks(db, grid, out.start, out.blocks,
              [](TriangleBlock& b, std::uint32_t lane, std::uint32_t id, const Primitive& p) {
                for (int vtx = 0; vtx < 3; ++vtx)
                  for (int a = 0; a < 3; ++a) b.v[vtx][a][lane] = p.data[3 * vtx + a];
                b.primitive[lane] = id;
              });
  if (kinds == PackKinds::kTrianglesAndSpheres) {
    // Each packed cell holds its own copy of its spheres. Where spheres
    // are listed in many cells (large overlapping spheres) the copies would
    // outgrow the cache and run slower than the lists: they are capped at
    // kSphereBlockBudget times the blocks that would hold each sphere once.
    std::uint64_t spheres = 0;
    for (const Primitive& p : db.primitives) spheres += p.kind == PrimitiveKind::kSphere;
    std::vector<std::uint32_t> start;
    const std::uint64_t budget = kSphereBlockBudget * ((spheres + kBlockLanes - 1) / kBlockLanes);
    const std::uint32_t n =
        plan_blocks(db, grid, min_triangles, PrimitiveKind::kSphere, std::max<std::uint64_t>(budget, 1), start);
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
