// A node's database in the data-oriented mode: the primitives overlapping
// its region and a local grid over the region (docs/architecture.md, "One tracer,
// several data views": RegionView; paper, "Algorithm overview": "all the
// processors subdivide the region for which they are responsible").
//
// Place in the data flow: host Database + Partition -> make_region_databases
// (host, before the run: per region the primitives whose screen-frame
// footprint overlaps the region's rectangle, a local core::Database and a
// core::Grid built over the region's part of the scene) -> copied into the
// node's arena -> RegionView -> core traversal (traverse.h) on the node.
//
// Choices:
// * A primitive overlapping several regions is copied into each (the
//   paper's "shared objects"); a hit is accepted only inside the ray's
//   [t_enter, t_exit) interval of the region (node_tracer.cpp), so the closest
//   hit is the sequential one. Tests of shared primitives are counted (an
//   upper bound of the paper's "repeated intersections").
// * Overlap is conservative: the 2D bounding box of the primitive's
//   projection on the screen frame (triangle vertices; sphere centre +-
//   radius; cone end centres +- the larger radius) against the region's
//   rectangle grown by `pad` (1e-4 of the extent plus float rounding).
// * The local grid covers the world box of the region's rectangle x the
//   scene's depth range, clipped to its primitives' bounds; core's grid
//   heuristic picks its resolution for the region's primitive count. Its
//   kind is the run's (GridParams::kind): a uniform grid, or an adaptive
//   one whose top grid covers the region and whose dense cells hold
//   sub-grids (core/grid.h); RegionView hands the sub-grid tables to the
//   traversal as DirectView does, so both walk the same leaf cells.
// * Local primitives keep their global order (ascending global id) and
//   their NFF shape index; `pp` vertex normals are renumbered; every node
//   holds all materials (few, and addressed by index from the primitives).
#pragma once

#include <cstdint>
#include <vector>

#include "core/database.h"
#include "core/direct_view.h"
#include "core/grid.h"
#include "dataflow/region.h"

namespace raynode::dataflow {

/// One region's database as the host builds it.
struct RegionDatabase {
  core::Database db;                   ///< primitives, vertex normals, all materials; bounds = the local grid's box
  core::Grid grid;                     ///< local grid over `db` (uniform or adaptive, GridParams::kind)
  std::vector<std::uint32_t> global;   ///< global primitive id of each local primitive
  std::vector<std::uint8_t> shared;    ///< 1 if the primitive is also in another region
  /// Bytes the node needs for it: primitives, vertex normals, materials,
  /// grid arrays (core::Grid::bytes: cell lists and, adaptive, the
  /// sub-grids, cell entries and top-cell bits), shared flags.
  std::size_t bytes() const;
};

/// The databases of every region of `partition` (index = region); each
/// local grid is built with `grid_params` (its kind included).
std::vector<RegionDatabase> make_region_databases(const core::Database& db, const Partition& partition,
                                                  const core::GridParams& grid_params = {});

/// The database view over a region's arrays (in a node's arena). Counts
/// the intersection tests of shared primitives into `*shared_tests`. With
/// an adaptive local grid (`arrays` with sub-grid tables) the cells it
/// reads lists of are leaf cells (core/grid.h, Grid). Owner thread only.
class RegionView {
 public:
  RegionView(const core::DatabaseArrays& arrays, const std::uint8_t* shared, std::uint64_t* shared_tests)
      : a_(arrays), shared_(shared), shared_tests_(shared_tests) {}

  const core::TopGridInfo& grid_info() const { return a_.grid; }
  /// The adaptive local grid's tables (all empty for a uniform grid); a
  /// cell visit returns kSubGridCode + i for a cell holding sub-grid i.
  core::SubGridTables sub_grid_tables() const { return {a_.sub_grids, a_.cell_entries}; }
  template <class F>
  std::uint32_t for_each_in_cell(std::uint32_t cell, F&& f) const {
    if (const std::uint32_t d = a_.empty_distance[cell]) return core::empty_leaf_code(d, a_.cell_entries.data(), cell);
    const std::uint32_t* p = a_.cell_primitives.data();
    for (std::uint32_t i = a_.cell_start[cell], e = a_.cell_start[cell + 1]; i < e; ++i) f(p[i]);
    return 0;
  }
  /// The traversal calls this once per intersection test.
  const core::Primitive& primitive(std::uint32_t id) const {
    *shared_tests_ += shared_[id];
    return a_.primitives[id];
  }
  /// The same record, for shading (not counted).
  const core::Primitive& shading_primitive(std::uint32_t id) const { return a_.primitives[id]; }
  const core::Material& material(std::uint32_t id) const { return a_.materials[id]; }
  const core::TriangleNormals& vertex_normals(std::uint32_t id) const { return a_.vertex_normals[id]; }

 private:
  core::DatabaseArrays a_;
  const std::uint8_t* shared_;
  std::uint64_t* shared_tests_;
};

}  // namespace raynode::dataflow
