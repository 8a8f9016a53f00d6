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
// a cell plus 8 ulps of the larger of the top grid's coordinate magnitude
// and the tracing frame's), so rounding in the 3D-DDA can never skip a
// primitive. The tracer keeps its rounding at that magnitude: a ray from
// beyond the frame (a far floor's point, a distant eye) is tested from
// where its line enters the frame's cube, that point computed in double
// (traverse.h, framed_ray). So a stadium floor beside the adaptive grid's
// top grid does not widen every cell over the object. Triangles use the separating-axis
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
//
// Adaptive grid (GridKind::kAdaptive; adaptive voxel subdivision, Jevans &
// Wyvill 1989, with per-cell resolutions chosen as in Kalojanov, Billeter &
// Slusallek, "Two-Level Grids for Ray Tracing on GPUs", EG 2011). A top grid
// over the same padded box, then, recursively to level max_depth, every
// cell that lists many primitives gets its own uniform sub-grid over the
// part of its box that its primitives reach (their bounds' union, grown by
// the cell inflation and clipped to the cell: a mesh in a stadium-sized
// top cell gets its sub-cells over the mesh, and a ray that misses that
// box costs one slab test). A floor under that mesh would stretch the box
// over the whole cell: a few primitives large in the cell (kLargeSpan,
// kLargeShare) are kept out of the sub-grid, in a leaf of their own that
// the walk tests before the sub-grid (SubGrid::large_list), when the
// others' box is then at most half the cell's on some axis; C_sub below
// gains their count, tested once per ray (mailbox). The whole scene is
// split the same way before the top grid is built: at most kMaxTopLarge
// primitives large in the scene's box (a floor, the walls of a room),
// when the others' box is at most half the scene's on some axis, are
// listed in one leaf beside the top grid, which a ray tests first unless it
// cannot reach their slab (TopGridInfo::large_slab: a ray leaving a floor or
// rising above it), and the top grid covers only the others' padded box (pad_box); the split is
// repeated in that box while it finds large primitives and the leaf stays
// within kMaxTopLarge (nested scales: an object on its own ground on a
// stadium floor). So a mesh on a stadium floor or in a room gets the top
// grid's cells over the mesh, and a ray that only meets the floor costs a
// test and no walk. Cost model, per ray crossing a cell that lists n
// primitives (times in units of one primitive test):
//   leaf:      C_leaf = n
//   sub-grid:  C_sub  ~ C_enter + k * (C_step + r),
// where C_enter (the sub-walk's slab test and 3D-DDA setup) costs a few
// tests, k ~ cbrt(m) cells of the m-cell sub-grid are crossed, and r is the
// expected references per sub-cell, r = sum_i prod_a min(res_a,
// e_ia / cell_a + 1) / m for primitive i's extent e_ia clipped to the cell
// (a primitive as wide as the cell is listed in every sub-cell; a sphere in
// at most the ~1.5 cells per cell area its surface inside the cell crosses,
// 4 pi r^2 scaled by the clipped share of its box to the power 2/3). Both
// resolutions follow Kalojanov's rule, cells = lambda * n with cubic-ish
// cells: lambda_top = top_density (2) cells per primitive for the top grid,
// lambda = density (2) per listed primitive for a sub-grid (at most
// kMaxSubGridResolution per axis), a primitive counting as its test's cost:
// a triangle triangle_weight (a quarter where packed cells test eight at
// once), a sphere 1, a cone cone_weight (4). A cell gets a sub-grid only
// where it pays by the model: its primitives weigh
// at least sub_grid_min (32) in units of one listed triangle's test,
// counted as the resolution rule counts them (below it C_enter + k *
// C_step is not won back; a packed triangle weighs a quarter, so a packed
// leaf needs 128 triangles: at 64, Balls4 tessellated traced 1.1x slower;
// a cone weighs kConeWeight), at least two sub-cells, and
// r <= kSubGridGain * n (the sub-grid separates the primitives;
// overlapping large primitives stay in one leaf, so references cannot
// multiply level by level), and k * r <= sub_grid_walk_share * n with
// k = cbrt(m) (a ray meets under a third of the leaf's references in the
// sub-grid: each it meets costs a test or a mailbox lookup, and each of its
// k sub-cells a step, so a sub-grid that only halves them is not won back;
// without the bound, shells:5's overlapping spheres grew 5,761 primitives
// into 2.45 M references in 45 sub-grids; bounded by n, into 1.19 M in 5,
// at k * r = 0.37-0.98 n and the uniform grid's rays/s; every refined cell
// of the other scenes of the accel corpus is at or below 0.22 n). The defaults
// were chosen with `raynode bench accel` (docs/architecture.md, "Scenes",
// Grid): a coarser top grid (lambda_top 1/16, n_min 8, Kalojanov's shape)
// won a little more on a mesh in a stadium but cost 2-3x on the paper's
// evenly filled scenes, where every top cell's sub-walk setup is paid.
//
// Per-axis resolutions (adaptive): the cube-root rule over the axes that
// would get at least one cell; an axis that would get less gets one and the
// budget is spread again over the others. So a thin axis gets one cell only
// when a cell would be thicker than the box, never merely because it is
// thin beside the others (the uniform rule's "flat axis", below 1e-3 of the
// largest extent, gives a 1000x stadium floor with a mesh on it one cell in
// height; the adaptive grid's sub-grids over the mesh divide that axis).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "core/database.h"
#include "core/math.h"

namespace raynode::core {

/// Which grid build_grid makes.
enum class GridKind : std::uint8_t {
  kUniform,   ///< one resolution for the whole scene (the paper's)
  kAdaptive,  ///< a coarse top grid whose dense cells hold their own sub-grids (see below)
};
/// "uniform" or "adaptive".
const char* grid_kind_name(GridKind kind);

/// GridParams::cone_weight's default: a ray/cone test costs about four
/// ray/triangle or ray/sphere tests (the model clock's fit, core/cost_model.h:
/// 28.2 ns against 6.5 and 6.6), so a cone gets four times a triangle's
/// cells. Measured with `raynode bench accel` over the scenes with cones
/// (Rings, Tree, Lattice, Jacks): 2, 4, 6 and 8 all beat 1, by 5% at the
/// geometric mean, and 4 to 8 are alike.
inline constexpr float kConeWeight = 4.0f;

/// Grid build options.
struct GridParams {
  /// Uniform by default here (the paper's grid, what library callers and
  /// tests got before); every command asks for kAdaptive unless given
  /// --grid uniform (dataflow: each region's local grid).
  GridKind kind = GridKind::kUniform;
  float density = 2.0f;      ///< target cells per primitive (lambda)
  int max_resolution = 512;  ///< cap per axis
  /// Force a resolution (all three > 0) instead of the heuristic.
  int resolution[3] = {0, 0, 0};
  /// Record empty-space distances (Grid::empty_distance); false records 1
  /// for every empty cell, so the 3D-DDA steps cell by cell as in the paper.
  bool skip_empty = true;
  /// Adaptive only: top grid cells per primitive (lambda_top; cost model above).
  float top_density = 2.0f;
  /// Adaptive only: a cell whose primitives weigh less, counted as the
  /// resolution rule counts them (triangle_weight, cone_weight), stays a
  /// leaf (n_min, in listed triangle tests).
  float sub_grid_min = 32.0f;
  /// Adaptive only: the deepest sub-grid level (the top grid is level 0).
  int max_depth = 2;
  /// Adaptive only: a cell gets a sub-grid only if the references a ray
  /// meets crossing it, cbrt(sub-cells) * references per sub-cell, are at
  /// most this fraction of the cell's primitives (cost model above; 1
  /// refines wherever a ray meets no more than in the leaf).
  double sub_grid_walk_share = 0.3;
  /// Adaptive only: list the scene's few large primitives beside the top
  /// grid, which then covers only the others' box (above); false keeps
  /// every primitive in the top grid.
  bool large_beside_top = true;
  /// Adaptive only: what a triangle counts for in the resolution rule,
  /// cells = density x (spheres + cone_weight x cones + triangle_weight x
  /// triangles), at every level, and against sub_grid_min. 1 (the default)
  /// for a tracer that tests each listed triangle on its own;
  /// kPackedTriangleWeight where the tracer tests
  /// packed cells' triangles a block at a time (cell_blocks.h,
  /// grid_params_for_packed_cells), so fewer, fuller cells pay.
  float triangle_weight = 1.0f;
  /// Adaptive only: what a cone counts for, in the resolution rule and
  /// against sub_grid_min (kConeWeight: its test's cost in triangle tests).
  float cone_weight = kConeWeight;
  /// TopGridInfo::frame_magnitude to give the grid; 0 (the default): the
  /// database's own, frame_magnitude(db). dataflow's region grids get the
  /// whole scene's, so that every mode tests a ray in the same frame.
  float frame_magnitude = 0;
};

/// GridParams::triangle_weight of a tracer that tests packed triangle
/// cells (--pack-cells) eight triangles a block: at the default density,
/// half a cell per triangle. Chosen with `raynode bench accel --grid-density`
/// over the triangle scenes of the accel corpus, flat from 0.125 to 0.25
/// and slower above (docs/results.md, "Fewer, fuller cells for packed
/// triangles"); listed triangles, tested one by one, keep 1.
inline constexpr float kPackedTriangleWeight = 0.25f;

/// `params` with triangle_weight kPackedTriangleWeight when `pack_min` > 0
/// (the tracer packs cells of at least pack_min triangles), else as given.
inline GridParams grid_params_for_packed_cells(GridParams params, std::uint32_t pack_min) {
  if (pack_min > 0) params.triangle_weight = kPackedTriangleWeight;
  return params;
}

/// Adaptive: the most cells of a sub-grid per axis.
inline constexpr int kMaxSubGridResolution = 64;
/// Adaptive: a cell gets a sub-grid only if a ray's expected tests in it
/// are at most this fraction of the cell's primitives (cost model above).
inline constexpr double kSubGridGain = 0.5;

/// Cap of Grid::empty_distance (it is stored in a byte; 255 is kSubGridMark).
inline constexpr std::uint32_t kMaxEmptyDistance = 254;
/// Adaptive: Grid::empty_distance of a cell holding a sub-grid (its
/// placeholder leaf), so that a view's cell visit, which reads that byte
/// first, tells the cell apart with no other read.
inline constexpr std::uint32_t kSubGridMark = 255;
/// A view's cell visit returns kSubGridCode + i for a cell that holds
/// sub-grid i (traverse.h, walk_cells): above every empty-space distance,
/// so one compare tells them apart.
inline constexpr std::uint32_t kSubGridCode = kSubGridMark + 1;

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

/// A slab lo <= normal . p <= hi (unit normal, world units, in double)
/// that holds every point of some primitives: the scene's large primitives
/// beside the adaptive grid's top grid (TopGridInfo::large_slab), with the
/// normal of the largest of them, so that a floor's slab is the floor's
/// plane. By default the whole space, which every ray meets.
struct PrimitiveSlab {
  double normal[3] = {0, 0, 1};
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();

  /// False when `ray` cannot meet the slab from max(tmin, 0) on, or from
  /// tmin on for a piece of a ray in the tracing frame (tmin < 0,
  /// framed_ray): that point lies outside the slab (beyond 2^-40 of the
  /// coordinates' magnitude, far above the rounding of the dot products in
  /// double) and the ray does not move toward it (a ray parallel to the
  /// slab stays outside). Exact geometry: a primitive in the slab can be
  /// hit only where this is true.
  bool may_meet(const Ray& ray) const {
    const double ox = ray.origin.x, oy = ray.origin.y, oz = ray.origin.z;
    const double dx = ray.direction.x, dy = ray.direction.y, dz = ray.direction.z;
    const double ds = normal[0] * dx + normal[1] * dy + normal[2] * dz;
    const double back = ray.tmin < 0.0f ? double(ray.tmin) : 0.0;
    const double s = normal[0] * ox + normal[1] * oy + normal[2] * oz + back * ds;
    const double tol = 0x1p-40 * (std::fabs(ox) + std::fabs(oy) + std::fabs(oz) -
                                  back * (std::fabs(dx) + std::fabs(dy) + std::fabs(dz)));
    if (s > hi + tol) return ds < 0.0;
    if (s < lo - tol) return ds > 0.0;
    return true;
  }
};

/// The top grid's GridInfo, with the tracing frame: a ray whose origin lies
/// outside the cube [-frame_magnitude, frame_magnitude]^3 is tested from
/// where its line enters that cube (traverse.h, framed_ray), so that its
/// rounding is the scene's objects' and not the far origin's; the cells'
/// margins hold that rounding (header comment). What every node
/// replicates; a sub-grid's record is a plain GridInfo.
struct TopGridInfo : GridInfo {
  float frame_magnitude = 0;  ///< world units; 0: every ray as it is
  /// Adaptive: a slab holding the scene's large primitives beside the top
  /// grid (SubGridTables::top_large_leaf), which a ray tests only when it
  /// may meet the slab (a floor is not tested by the rays that leave it or
  /// rise above it); the whole space when there are none.
  PrimitiveSlab large_slab;
};

/// One grid of an adaptive grid's hierarchy: the top grid (index 0) or the
/// sub-grid of one cell of a coarser grid. Its cell c is leaf cell
/// first_entry + c, and its entry Grid::cell_entries[first_entry + c] is
/// that leaf id, or kSubGridEntry | the index of the cell's own sub-grid
/// (the leaf is then a placeholder listing nothing, its empty distance
/// kSubGridMark). So the top grid's cell c is leaf c, and the top walk
/// reads an entry only for a cell whose distance byte is kSubGridMark.
///
/// Large primitives beside a sub-grid: where a few of a cell's primitives
/// span most of it (a floor or a wall under a mesh), they stay out of the
/// sub-grid, which then covers only the others' box, and are listed in one
/// more leaf, first_entry + info.cell_count(), right after the sub-grid's
/// cells (large_list). A walk tests that leaf before the sub-grid's cells.
/// The top grid's large_list lists the scene's large primitives (above),
/// which its box may not hold.
struct SubGrid {
  /// bounds: the part of the parent cell its primitives reach (within GridInfo::cell_bounds)
  GridInfo info;
  std::uint32_t first_entry = 0;  ///< its cells' entries in Grid::cell_entries
  std::uint32_t level = 0;        ///< 0 for the top grid, parent's level + 1 below
  bool large_list = false;        ///< leaf first_entry + info.cell_count() lists the parent cell's large primitives
};
/// No leaf (SubGridTables::top_large_leaf when the top grid has no large
/// primitives beside it).
inline constexpr std::uint32_t kNoLeaf = 0xFFFFFFFFu;
/// Tag bit of a cell entry naming a sub-grid (else the entry is a leaf cell id).
inline constexpr std::uint32_t kSubGridEntry = 0x80000000u;

/// An adaptive grid's hierarchy as a view hands it to the traversal
/// (traverse.h, walk_cells): both empty for a uniform grid.
struct SubGridTables {
  std::span<const SubGrid> sub_grids;        ///< Grid::sub_grids
  std::span<const std::uint32_t> cell_entries;  ///< Grid::cell_entries

  /// The leaf listing the scene's large primitives beside the top grid
  /// (the top grid's large_list), or kNoLeaf.
  std::uint32_t top_large_leaf() const {
    if (sub_grids.empty() || !sub_grids[0].large_list) return kNoLeaf;
    return sub_grids[0].first_entry + sub_grids[0].info.cell_count();
  }
};

/// What a view's cell visit returns for leaf `cell` whose empty distance
/// byte `d` is not 0: d for an empty leaf, or kSubGridCode + i for a cell
/// holding sub-grid i (d == kSubGridMark; `cell_entries`: Grid::cell_entries).
inline std::uint32_t empty_leaf_code(std::uint32_t d, const std::uint32_t* cell_entries, std::uint32_t cell) {
  return d != kSubGridMark ? d : kSubGridCode + (cell_entries[cell] & ~kSubGridEntry);
}

/// Adaptive: a primitive is large in a cell when, clipped to the cell, it
/// spans at least this share of the cell on two axes or more.
inline constexpr double kLargeSpan = 0.5;
/// Adaptive: the large primitives are set beside a sub-grid only when they
/// are at most this share of the cell's primitives.
inline constexpr double kLargeShare = 1.0 / 16.0;
/// Adaptive: the most primitives large in the whole scene that are set
/// beside the top grid (every ray tests them, so only a few).
inline constexpr std::size_t kMaxTopLarge = 8;

/// A built grid: GridInfo plus, for leaf cell c, the primitive ids
/// cell_primitives[cell_start[c] .. cell_start[c+1]), ascending.
///
/// Uniform (sub_grids empty): the leaf cells are the cells of `info`,
/// numbered by GridInfo::cell_index. Adaptive (see below): `info` is
/// the top grid (== sub_grids[0].info); every cell of every grid in
/// sub_grids is either a leaf cell (numbered globally, in build order) or
/// holds a sub-grid; cell_start, cell_primitives and empty_distance run over
/// the leaf cells, so views read a leaf's list as they read a uniform cell's.
/// A leaf's empty distance counts cells of its own grid.
struct Grid {
  TopGridInfo info;  ///< the (top) grid; adaptive: its bounds may hold only the primitives not beside it (SubGrid)
  std::vector<std::uint32_t> cell_start;       ///< cell_count()+1 offsets
  std::vector<std::uint32_t> cell_primitives;  ///< primitive ids into Database::primitives
  /// Per cell: 0 if it lists a primitive, else the Chebyshev distance in
  /// cells to the nearest cell that does (cells beyond the grid count as
  /// empty), capped at kMaxEmptyDistance; 1 for every empty cell when built
  /// with skip_empty false; kSubGridMark for an adaptive grid's placeholder
  /// leaf (a cell holding a sub-grid, which counts as listing primitives in
  /// its grid's distances).
  std::vector<std::uint8_t> empty_distance;
  std::vector<SubGrid> sub_grids;            ///< adaptive only: [0] the top grid, then sub-grids
  std::vector<std::uint32_t> cell_entries;   ///< adaptive only: per cell of every sub-grid (see SubGrid)

  /// What build_grid was asked for. An adaptive build that refines no cell
  /// keeps only its top grid (sub_grids and cell_entries empty), which
  /// every view walks as a uniform grid.
  GridKind built_as = GridKind::kUniform;

  GridKind kind() const { return built_as; }
  /// Leaf cells (== info.cell_count() for a uniform grid).
  std::uint32_t leaf_cells() const { return cell_start.empty() ? 0 : std::uint32_t(cell_start.size() - 1); }
  /// Grids below the top one (0 for a uniform grid).
  std::size_t sub_grid_count() const { return sub_grids.empty() ? 0 : sub_grids.size() - 1; }
  /// Deepest level (0: no sub-grid).
  std::uint32_t depth() const;

  /// Statistics for reports and benchmarks.
  std::size_t references() const { return cell_primitives.size(); }
  std::size_t empty_cells() const;
  std::size_t bytes() const {
    return (cell_start.size() + cell_primitives.size() + cell_entries.size()) * sizeof(std::uint32_t) +
           empty_distance.size() + sub_grids.size() * sizeof(SubGrid);
  }
};

/// Chooses the resolution by the heuristic above.
void choose_grid_resolution(const Bounds3& bounds, std::size_t primitive_count, const GridParams& params,
                            int res[3]);

/// Builds the grid over every primitive of `db` (params.kind: uniform, or
/// adaptive as build_adaptive_grid) but its degenerate triangles
/// (triangle_is_degenerate, which no ray hits; a database from make_database
/// holds none by default), so that the walk need not check a would-be hit
/// for one. An empty database gives a 1x1x1 grid with no references.
/// Deterministic (same input, same lists, whatever the threads): the
/// cells' primitive lists and the sub-grid choices are made on all of
/// oneTBB's threads (as Embree builds its BVH) once a grid lists more than
/// 2048 primitives, then merged in primitive and cell order.
Grid build_grid(const Database& db, const GridParams& params = {});

/// The padded world box of the uniform grid and of the adaptive grid's
/// top grid (unless the scene's large primitives lie beside it: then the
/// others' box, padded the same way): pad_box(db.bounds).
Bounds3 grid_bounds(const Database& db);

/// `b` (or [-1,1]^3 when empty) grown by max(1e-4 of its largest extent,
/// 16 ulps of its largest coordinate) on every side.
Bounds3 pad_box(Bounds3 b);

/// The largest coordinate magnitude of box `b` (world units): the cube
/// [-m, m]^3 holds it.
inline float coordinate_magnitude(const Bounds3& b) {
  return std::max(max_component(abs(b.lower)), max_component(abs(b.upper)));
}

/// The tracing frame's size against the objects' box (frame_magnitude).
/// Above 1, so that the frame's edge lies well away from every object and a
/// piece of a ray before it meets none; the larger, the fewer rays are split
/// (a ray from the ground near the objects is not) and the wider every
/// cell's margin for rounding, 8 float spacings of the frame's magnitude.
inline constexpr float kFrameScale = 4.0f;

/// The tracing frame of `db` (TopGridInfo::frame_magnitude): kFrameScale
/// times the coordinate magnitude of the box its objects fill once its few
/// large primitives (a floor, a stadium) are set aside, as the adaptive
/// grid's top grid covers it, whatever the grid kind. World units.
float frame_magnitude(const Database& db);

/// Fills grid.empty_distance from grid.cell_start (see Grid); with
/// skip_empty false, 0 for a non-empty cell and 1 for an empty one.
void compute_empty_distance(Grid& grid, bool skip_empty = true);

/// Separating-axis triangle/box overlap test (Akenine-Moeller 2001).
bool triangle_overlaps_box(const Vec3& v0, const Vec3& v1, const Vec3& v2, const Bounds3& box);

}  // namespace raynode::core
