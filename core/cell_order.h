// The order in which a grid's cells are numbered for a view's cell
// directory. The traversal (traverse.h) hands each visited cell to the view
// by its number, its *key*; DirectView and the other plain views use the
// linear order (x fastest, then y, then z: GridInfo::cell_index), which the
// 3D-DDA keeps with one add per step.
//
// svm's paged directory may be *bricked* instead (svm/paged_database.h):
// the grid is cut into bricks of dims[0] x dims[1] x dims[2] cells, each
// brick numbered linearly inside and given a whole directory page, bricks
// in linear order. A ray then crosses a new directory page every few cells
// on any axis, not at nearly every step across rows; a node whose rays
// sweep a frustum fetches the bricks it meets instead of every row it
// crosses (docs/architecture.md, "svm").
//
// The key is separable, key(x, y, z) = K_x[x] + K_y[y] + K_z[z], with
//   K_x[x] = (x / dims[0]) * brick_stride[0] + x % dims[0]
//   K_y[y] = (y / dims[1]) * brick_stride[1] + (y % dims[1]) * dims[0]
//   K_z[z] = (z / dims[2]) * brick_stride[2] + (z % dims[2]) * dims[0] * dims[1]
// where brick_stride = (slots, slots * bricks_x, slots * bricks_x * bricks_y)
// and `slots` the entries of a brick's page. So a walk keeps the key with
// one table read per step: CellKeyTables holds K_a and the step's change
// for each axis and direction, O(resolution) words that every node
// replicates with the grid's description.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "core/grid.h"

namespace raynode::core {

/// A brick shape for a grid's directory, in cells per axis (each >= 1).
struct CellBricks {
  std::array<std::int32_t, 3> dims{1, 1, 1};
  std::int32_t slots = 1;  ///< keys per brick (>= dims' product): a brick's page's entries

  std::int32_t cells() const { return dims[0] * dims[1] * dims[2]; }
  /// Bricks along axis a of `g`.
  std::int32_t bricks(const GridInfo& g, int a) const { return (g.res[a] + dims[a] - 1) / dims[a]; }
  /// Keys the whole grid needs: bricks x slots.
  std::uint64_t keys(const GridInfo& g) const {
    return std::uint64_t(bricks(g, 0)) * std::uint64_t(bricks(g, 1)) * std::uint64_t(bricks(g, 2)) *
           std::uint64_t(slots);
  }
  /// Axis a's part of a cell's key (the file comment's K_a[c]), 0 <= c < g.res[a].
  std::int64_t axis_key(const GridInfo& g, int a, std::int32_t c) const {
    std::int64_t stride = slots, inner = 1;
    for (int b = 0; b < a; ++b) {
      stride *= bricks(g, b);
      inner *= dims[b];
    }
    return std::int64_t(c / dims[a]) * stride + std::int64_t(c % dims[a]) * inner;
  }
  /// The key of cell (x, y, z).
  std::uint64_t key(const GridInfo& g, std::int32_t x, std::int32_t y, std::int32_t z) const {
    return std::uint64_t(axis_key(g, 0, x) + axis_key(g, 1, y) + axis_key(g, 2, z));
  }
};

/// The brick shape for a directory of `slots` entries per page (>= 1):
/// the one, among shapes of at most `slots` cells and at most the grid's
/// resolution per axis, that minimises the pages a ray of random direction
/// meets per unit of length (sum over the axes of 1 / dims[a]) times the
/// directory's growth over the linear order (its bricks' pages against the
/// cells' entries). A cube-like brick that tiles the grid with little
/// padding wins. Deterministic; O(slots log slots) shapes tried. Throws
/// std::invalid_argument for slots < 1.
CellBricks choose_cell_bricks(const GridInfo& g, std::int32_t slots);

/// The replicated tables of a bricked walk, walk_grid's bricked order (file
/// comment): for each axis a, K_a[c] for c in [0, res[a]) and the key's
/// change for a step across boundary b (between cells b - 1 and b), up
/// (+1 direction) and down (-1), for b in [0, res[a]] (the walk indexes
/// them with the boundary it crosses, 1 <= b < res[a]; the ends are 0).
/// Plain words in one buffer, so a node can keep them in its arena.
struct CellKeyTables {
  /// Words needed for grid `g`: per axis, res + 2 (res + 1).
  static std::size_t words(const GridInfo& g) {
    return std::size_t(3 * g.res[0] + 2) + std::size_t(3 * g.res[1] + 2) + std::size_t(3 * g.res[2] + 2);
  }
  /// Fills `buffer` (words(g) words) for `bricks` and points the tables
  /// into it. Throws std::length_error when a key does not fit 31 bits.
  static CellKeyTables build(const GridInfo& g, const CellBricks& bricks, std::span<std::int32_t> buffer);

  const std::int32_t* key[3] = {nullptr, nullptr, nullptr};   ///< K_a, res[a] words
  const std::int32_t* up[3] = {nullptr, nullptr, nullptr};    ///< res[a] + 1 words
  const std::int32_t* down[3] = {nullptr, nullptr, nullptr};  ///< res[a] + 1 words (up negated)
};

/// The linear cell order (GridInfo::cell_index), walk_grid's default; a
/// CellKeyTables is the bricked one.
struct LinearCellOrder {};

}  // namespace raynode::core
