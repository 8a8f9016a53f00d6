// Load estimate of the data-oriented mode (paper, "Static load balancing",
// steps 1 and 2; docs/architecture.md, "dataflow"): the host traces a subsample of the
// pixels — one pixel per `subsample` x `subsample` block, 8 giving the
// paper's 1.5% — with the sequential tracer and charges the traversal work
// of every ray (primary, shadow, reflected, refracted) to the cells of a 2D
// grid over the scene extent in the camera's screen x and y.
//
// What is charged, and where: each visited 3D grid cell costs 1 (the cell
// step) plus the length of its primitive list (the intersection tests it
// causes, before mailboxing), charged to the 2D cost cell under the 3D
// cell's centre projected onto the screen frame (region.h). So the cost
// lands where the work happens — the same place a region's node will do it.
// With an adaptive host grid the visited cells are leaf cells, each at the
// centre of its own box (a top cell or a sub-grid's cell); a cell holding a
// sub-grid is never visited itself, its leaves are. The leaf of the scene's
// large primitives beside the top grid (a floor; every ray tests it, and
// each region tests its own copy) has no place of its own: its work is
// added to the cost cells in proportion to their other work.
// The work is counted by a view wrapper (CostView) around the host's
// DirectView, through the database-view concept of core/traverse.h: the
// tracer itself is unchanged.
//
// Place in the data flow: host Database + Grid + camera -> estimate_load ->
// CostGrid -> make_partition (region.h). Host work before the run, outside
// virtual time; its wall time is reported on its own.
#pragma once

#include <cstdint>
#include <vector>

#include "core/camera.h"
#include "core/database.h"
#include "core/direct_view.h"
#include "core/grid.h"
#include "core/shade.h"
#include "dataflow/region.h"

namespace raynode::dataflow {

/// A database view that charges every visited cell's work to a cost grid.
/// Owner thread only; refers to the base view and the arrays it is given.
class CostView {
 public:
  /// `bin_of_cell[c]` = cost-grid index of leaf cell c (cost_bins_of_cells);
  /// `cost` the grid's cells; `beside_top` sums the work of the leaf of
  /// the scene's large primitives beside an adaptive top grid (core/grid.h),
  /// which estimate_load adds in proportion to the other cells' work.
  CostView(const core::DirectView& base, const std::uint32_t* bin_of_cell, double* cost, double* beside_top)
      : base_(base),
        bin_of_cell_(bin_of_cell),
        cost_(cost),
        beside_top_(beside_top),
        large_leaf_(base.sub_grid_tables().top_large_leaf()) {}
  const core::TopGridInfo& grid_info() const { return base_.grid_info(); }
  /// The base's sub-grid tables: an adaptive grid is walked leaf by leaf.
  core::SubGridTables sub_grid_tables() const { return base_.sub_grid_tables(); }
  template <class F>
  std::uint32_t for_each_in_cell(std::uint32_t cell, F&& f) const {
    const auto& a = base_.arrays();
    const double work = 1.0 + double(a.cell_start[cell + 1] - a.cell_start[cell]);
    if (cell == large_leaf_) [[unlikely]]
      *beside_top_ += work;
    else
      cost_[bin_of_cell_[cell]] += work;
    return base_.for_each_in_cell(cell, f);
  }
  const core::Primitive& primitive(std::uint32_t id) const { return base_.primitive(id); }
  const core::Material& material(std::uint32_t id) const { return base_.material(id); }
  const core::TriangleNormals& vertex_normals(std::uint32_t id) const { return base_.vertex_normals(id); }

 private:
  const core::DirectView& base_;
  const std::uint32_t* bin_of_cell_;
  double* cost_;
  double* beside_top_;
  std::uint32_t large_leaf_;  // core::kNoLeaf when there is none
};

/// Options of the estimate.
struct EstimateParams {
  int subsample = 8;     ///< one traced pixel per subsample x subsample block (>= 1)
  int resolution = 64;   ///< cost cells along the extent's longer screen side (>= 1)
  int spp = 1;           ///< samples per pixel, as the frame will use
  int max_depth = 5;
  float min_weight = 0;
  core::ShadowRays shadow_rays = core::ShadowRays::kFacing;
  /// Regions the cost grid will be cut into: a cell holding more than half
  /// a region's share makes estimate_load charge again on a finer grid.
  std::uint32_t regions = 1;
};
/// The finest cost grid estimate_load refines to (cells along the longer side).
inline constexpr int kMaxEstimateResolution = 1024;

/// The estimate's result.
struct LoadEstimate {
  /// Charged work per 2D cell (cells visited + listed primitives), over
  /// the extent given or, when `refined`, over the part of it that was
  /// charged (cost.extent).
  CostGrid cost;
  /// True when the subsample was charged again: over the part of the
  /// extent that holds the work, or on a finer grid (estimate_load).
  bool refined = false;
  std::uint64_t pixels = 0;    ///< pixels traced
  std::uint64_t rays = 0;      ///< rays traced (all kinds)
  double seconds = 0;          ///< host wall time
};

/// Per leaf cell of `grid` (Grid::leaf_cells(), uniform or adaptive): the
/// index (by * nx + bx) of the cost cell of `cost`'s shape (extent, nx, ny;
/// its costs are not read) under the leaf's box centre projected on the
/// screen frame `frame`, clamped to the grid. A placeholder leaf (a cell
/// holding a sub-grid) gets its cell's centre's bin; a top grid's
/// placeholder is charged one step when a walk enters its sub-grid.
std::vector<std::uint32_t> cost_bins_of_cells(const core::Grid& grid, const CameraFrame& frame, const CostGrid& cost);

/// Traces the subsample of the width x height image of `camera` over `db`
/// and `grid` (uniform or adaptive) and returns the cost grid over `extent`
/// (screen frame `frame`). When the charged cells, padded by one, span less
/// than half the extent on an axis (a small model on a huge floor), the
/// subsample is traced again over that rectangle alone, so that the cuts
/// can fall inside the work (LoadEstimate::refined; pixels and rays are one
/// pass's). Then, while a cost cell holds more than half of a region's
/// share (params.regions), the grid is made four times finer, up to
/// kMaxEstimateResolution cells, and charged again. Throws
/// std::invalid_argument for bad params.
LoadEstimate estimate_load(const core::Database& db, const core::Grid& grid, const core::Camera& camera,
                           const CameraFrame& frame, const ScreenRect& extent, const EstimateParams& params);

/// A cost grid over `extent` with the same cell shape as estimate_load's,
/// every cell costing 1 (the `--partition equal` comparison).
CostGrid uniform_cost(const ScreenRect& extent, int resolution);

}  // namespace raynode::dataflow
