// DirectView: the database view over plain in-memory arrays. Used by
// sequential, shared and replicated modes (docs/architecture.md, "One tracer, several
// data views"): the host's Database + Grid, or a node's own copy of the
// same arrays in its arena (DatabaseArrays). Cheap to copy; refers to, does
// not own, the arrays, which must outlive it. Uniform or adaptive grid: the
// cells it reads lists of are leaf cells (grid.h, Grid).
#pragma once

#include <cstdint>
#include <span>

#include "core/cell_blocks.h"
#include "core/database.h"
#include "core/grid.h"
#include "core/traverse.h"

namespace raynode::core {

/// The per-object arrays a tracer reads, wherever they live (the host's
/// vectors or a node's arena): primitives, `pp` vertex normals, materials,
/// and the grid's CSR cell lists with its O(1) description; optionally the
/// grid's packed cells (cell_blocks.h).
struct DatabaseArrays {
  std::span<const Primitive> primitives;
  std::span<const TriangleNormals> vertex_normals;
  std::span<const Material> materials;
  std::span<const std::uint32_t> cell_start;       ///< cell_count()+1 offsets
  std::span<const std::uint32_t> cell_primitives;  ///< primitive ids
  std::span<const std::uint8_t> empty_distance;    ///< cell_count() empty-space distances (Grid::empty_distance; required)
  TopGridInfo grid;
  std::span<const std::uint32_t> block_start = {};  ///< CellBlocks::start, or empty: no packed cell
  std::span<const TriangleBlock> blocks = {};       ///< CellBlocks::blocks
  std::span<const std::uint32_t> sphere_block_start = {};  ///< CellBlocks::sphere_start, or empty: no packed sphere cell
  std::span<const SphereBlock> sphere_blocks = {};         ///< CellBlocks::sphere_blocks
  std::span<const SubGrid> sub_grids = {};          ///< Grid::sub_grids (adaptive), or empty: uniform
  std::span<const std::uint32_t> cell_entries = {};  ///< Grid::cell_entries (adaptive), or empty

  /// The arrays of a host database and grid, and the grid's packed cells
  /// if `blocks` is given (built from the same db and grid).
  static DatabaseArrays of(const Database& db, const Grid& grid, const CellBlocks* blocks = nullptr) {
    DatabaseArrays a{db.primitives, db.vertex_normals, db.materials, grid.cell_start, grid.cell_primitives,
                     grid.empty_distance, grid.info};
    a.sub_grids = grid.sub_grids;
    a.cell_entries = grid.cell_entries;
    if (blocks) {
      a.block_start = blocks->start;
      a.blocks = blocks->blocks;
      a.sphere_block_start = blocks->sphere_start;
      a.sphere_blocks = blocks->sphere_blocks;
    }
    return a;
  }
  /// Bytes of all arrays (what a node needs to hold a full copy).
  std::size_t bytes() const {
    return primitives.size_bytes() + vertex_normals.size_bytes() + materials.size_bytes() + cell_start.size_bytes() +
           cell_primitives.size_bytes() + empty_distance.size_bytes() + block_start.size_bytes() +
           blocks.size_bytes() + sphere_block_start.size_bytes() + sphere_blocks.size_bytes() +
           sub_grids.size_bytes() + cell_entries.size_bytes();
  }
};

class DirectView {
 public:
  /// `blocks`: the grid's packed cells (built from db and grid), or null.
  DirectView(const Database& db, const Grid& grid, const CellBlocks* blocks = nullptr)
      : a_(DatabaseArrays::of(db, grid, blocks)), db_(&db) {}
  explicit DirectView(const DatabaseArrays& arrays) : a_(arrays) {}

  const TopGridInfo& grid_info() const { return a_.grid; }
  /// The adaptive grid's sub-grids (empty for a uniform grid); the cells
  /// below are then leaf cells (Grid), and a cell visit returns
  /// kSubGridCode + i for a cell holding sub-grid i.
  SubGridTables sub_grid_tables() const { return {a_.sub_grids, a_.cell_entries}; }
  template <class F>
  std::uint32_t for_each_in_cell(std::uint32_t cell, F&& f) const {
    if (const std::uint32_t d = a_.empty_distance[cell]) return empty_leaf_code(d, a_.cell_entries.data(), cell);
    const std::uint32_t* p = a_.cell_primitives.data();
    for (std::uint32_t i = a_.cell_start[cell], e = a_.cell_start[cell + 1]; i < e; ++i) f(p[i]);
    return 0;
  }
  /// for_each_in_cell, except that a packed cell is handed whole to
  /// packed(const CellBlockSpan&), or packed(const SphereBlockSpan&),
  /// instead of id by id to f.
  template <class F, class P>
  std::uint32_t visit_cell(std::uint32_t cell, F&& f, P&& packed) const {
    if (const std::uint32_t d = a_.empty_distance[cell]) return empty_leaf_code(d, a_.cell_entries.data(), cell);
    const std::uint32_t b = a_.cell_start[cell], e = a_.cell_start[cell + 1];
    if (!a_.block_start.empty()) {
      const std::uint32_t k = a_.block_start[cell], k_end = a_.block_start[cell + 1];
      if (k != k_end) {
        packed(CellBlockSpan{a_.blocks.data() + k, k_end - k, e - b});
        return 0;
      }
    }
    if (!a_.sphere_block_start.empty()) {
      const std::uint32_t k = a_.sphere_block_start[cell], k_end = a_.sphere_block_start[cell + 1];
      if (k != k_end) {
        packed(SphereBlockSpan{a_.sphere_blocks.data() + k, k_end - k, e - b});
        return 0;
      }
    }
    const std::uint32_t* p = a_.cell_primitives.data();
    for (std::uint32_t i = b; i < e; ++i) f(p[i]);
    return 0;
  }
  const Primitive& primitive(std::uint32_t id) const { return a_.primitives[id]; }
  const Material& material(std::uint32_t id) const { return a_.materials[id]; }
  const TriangleNormals& vertex_normals(std::uint32_t id) const { return a_.vertex_normals[id]; }
  const DatabaseArrays& arrays() const { return a_; }
  /// The host database it was made from; only for views made from one.
  const Database& database() const { return *db_; }

 private:
  DatabaseArrays a_;
  const Database* db_ = nullptr;
};

// The walks over DirectView are compiled once, in render.cpp.
RAYNODE_TRAVERSAL_INSTANCES(extern, DirectView);

}  // namespace raynode::core
