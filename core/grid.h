// Uniform 3D grid over the tracing database: the object-access structure
// that svm pages and dataflow partitions (paper, "Object-access structure").
//
// Place in the data flow: Database -> build_grid -> Grid (bounds, resolution,
// per-cell primitive lists in CSR form) -> a database view (direct_view.h,
// svm's PagedView, dataflow's RegionView) -> traversal (traverse.h).
//
// Resolution heuristic (Cleary & Wyvill 1988; Woo 1992; the "lambda N"
// rule used by Ize et al. 2006): choose cells of equal edge so that the
// cell count is about density x N for N primitives,
//     r_i = clamp(round(extent_i * cbrt(density * N / volume)), 1, max_resolution),
// where flat axes (extent below 1e-3 of the largest) get one cell and the
// volume is taken over the other axes. `density` defaults to 2 cells per
// primitive (measured best or near-best on the SPD scenes with
// `raynode bench accel`; tunable with --grid-density).
//
// Cell membership is conservative: a primitive is listed in every cell its
// surface may touch, with the cell box inflated by a small epsilon (1e-4 of
// a cell plus a few ulps of the grid's coordinate magnitude), so rounding in
// the 3D-DDA can never skip a primitive. Triangles use the separating-axis
// triangle/box test (Akenine-Moeller 2001), spheres the box/sphere distance
// test (Arvo 1990), cones a capsule test (the cell's bounding sphere against
// the axis segment grown by the larger radius).
//
// Empty-space skipping: every empty cell also records its Chebyshev
// distance, in cells, to the nearest cell that lists a primitive (a
// "proximity cloud", Cohen & Sheffer 1994): the cube of cells within
// distance d-1 of it is empty, so the 3D-DDA may jump to the cube's exit
// (traverse.h). Computed exactly by a two-pass 26-neighbour chamfer scan
// (the chessboard distance transform, Rosenfeld & Pfaltz 1966).
#pragma once

#include <cstdint>
#include <vector>

#include "core/database.h"
#include "core/math.h"

namespace raynode::core {

/// Grid build options.
struct GridParams {
  float density = 2.0f;      ///< target cells per primitive (lambda)
  int max_resolution = 512;  ///< cap per axis
  /// Force a resolution (all three > 0) instead of the heuristic.
  int resolution[3] = {0, 0, 0};
  /// Record empty-space distances (Grid::empty_distance); false records 1
  /// for every empty cell, so the 3D-DDA steps cell by cell as in the paper.
  bool skip_empty = true;
};

/// Cap of Grid::empty_distance (it is stored in a byte).
inline constexpr std::uint32_t kMaxEmptyDistance = 255;

/// O(1) description of a grid: what every node replicates (svm) and what the
/// traversal needs besides the cell lists.
struct GridInfo {
  Bounds3 bounds;            ///< world box covered by the cells
  int res[3] = {1, 1, 1};    ///< cells per axis
  Vec3 cell_size;            ///< world units per cell, per axis
  Vec3 inv_cell_size;        ///< 1 / cell_size (0 on a zero-extent axis)

  std::uint32_t cell_count() const { return std::uint32_t(res[0]) * res[1] * res[2]; }
  std::uint32_t cell_index(int x, int y, int z) const {
    return (std::uint32_t(z) * res[1] + std::uint32_t(y)) * res[0] + std::uint32_t(x);
  }
  /// World box of cell (x, y, z).
  Bounds3 cell_bounds(int x, int y, int z) const;
};

/// A built grid: GridInfo plus, for cell c, the primitive ids
/// cell_primitives[cell_start[c] .. cell_start[c+1]), ascending.
struct Grid {
  GridInfo info;
  std::vector<std::uint32_t> cell_start;       ///< cell_count()+1 offsets
  std::vector<std::uint32_t> cell_primitives;  ///< primitive ids into Database::primitives
  /// Per cell: 0 if it lists a primitive, else the Chebyshev distance in
  /// cells to the nearest cell that does (cells beyond the grid count as
  /// empty), capped at kMaxEmptyDistance; 1 for every empty cell when built
  /// with skip_empty false.
  std::vector<std::uint8_t> empty_distance;

  /// Statistics for reports and benchmarks.
  std::size_t references() const { return cell_primitives.size(); }
  std::size_t empty_cells() const;
  std::size_t bytes() const {
    return (cell_start.size() + cell_primitives.size()) * sizeof(std::uint32_t) + empty_distance.size();
  }
};

/// Chooses the resolution by the heuristic above.
void choose_grid_resolution(const Bounds3& bounds, std::size_t primitive_count, const GridParams& params,
                            int res[3]);

/// Builds the grid over every primitive of `db`. An empty database gives a
/// 1x1x1 grid with no references. Deterministic (same input, same lists).
Grid build_grid(const Database& db, const GridParams& params = {});

/// Fills grid.empty_distance from grid.cell_start (see Grid); with
/// skip_empty false, 0 for a non-empty cell and 1 for an empty one.
void compute_empty_distance(Grid& grid, bool skip_empty = true);

/// Separating-axis triangle/box overlap test (Akenine-Moeller 2001).
bool triangle_overlaps_box(const Vec3& v0, const Vec3& v1, const Vec3& v2, const Bounds3& box);

}  // namespace raynode::core
