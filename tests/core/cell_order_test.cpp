// Bricked cell orders (cell_order.h): the brick shape, the keys' layout in
// pages, and the 3D-DDA walking the same cells in either order.
#include <doctest/doctest.h>

#include <array>
#include <cstdint>
#include <stdexcept>
#include <utility>
#include <vector>

#include "core/cell_order.h"
#include "core/traverse.h"
#include "grid_test_support.h"

namespace {
using namespace raynode::core;
using namespace raynode::testing::grid;

GridInfo grid_of(int x, int y, int z) {
  GridInfo g;
  g.res[0] = x, g.res[1] = y, g.res[2] = z;
  return g;
}
}  // namespace

TEST_CASE("cell order: bricks fit a page, and every cell gets its own key, its brick's page") {
  for (const auto& [res, slots] : std::vector<std::pair<std::array<int, 3>, int>>{
           {{81, 81, 81}, 256}, {{7, 5, 3}, 256}, {{40, 33, 27}, 64}, {{1, 1, 200}, 16}, {{13, 1, 9}, 1024}}) {
    const GridInfo g = grid_of(res[0], res[1], res[2]);
    const int rx = res[0], ry = res[1], rz = res[2];
    CAPTURE(rx);
    CAPTURE(ry);
    CAPTURE(rz);
    CAPTURE(slots);
    const CellBricks b = choose_cell_bricks(g, slots);
    CHECK(b.slots == slots);
    CHECK(b.cells() <= slots);
    for (int a = 0; a < 3; ++a) CHECK((b.dims[a] >= 1 && b.dims[a] <= res[a]));
    std::vector<int> owner(b.keys(g), -1);
    for (int z = 0; z < res[2]; ++z)
      for (int y = 0; y < res[1]; ++y)
        for (int x = 0; x < res[0]; ++x) {
          const std::uint64_t k = b.key(g, x, y, z);
          REQUIRE(k < owner.size());
          CHECK(owner[k] == -1);  // one cell per key
          owner[k] = int(g.cell_index(x, y, z));
          // The brick's cells share a page of `slots` keys.
          const int brick = (x / b.dims[0]) + b.bricks(g, 0) * ((y / b.dims[1]) + b.bricks(g, 1) * (z / b.dims[2]));
          CHECK(k / std::uint64_t(slots) == std::uint64_t(brick));
        }
  }
  // The 81^3 grid of Tetra9 in 1 KiB pages of 4-byte entries: a cube-like
  // brick, not a row or a slab.
  const CellBricks t = choose_cell_bricks(grid_of(81, 81, 81), 256);
  for (int a = 0; a < 3; ++a) CHECK((t.dims[a] >= 4 && t.dims[a] <= 9));
  CHECK_THROWS_AS(choose_cell_bricks(grid_of(4, 4, 4), 0), std::invalid_argument);
}

TEST_CASE("cell order: the key tables step between neighbours' keys") {
  const GridInfo g = grid_of(17, 9, 30);
  const CellBricks b = choose_cell_bricks(g, 64);
  std::vector<std::int32_t> words(CellKeyTables::words(g));
  const CellKeyTables t = CellKeyTables::build(g, b, words);
  for (int a = 0; a < 3; ++a)
    for (int c = 0; c < g.res[a]; ++c) {
      CHECK(t.key[a][c] == b.axis_key(g, a, c));
      if (c + 1 < g.res[a]) {
        CHECK(t.key[a][c] + t.up[a][c + 1] == t.key[a][c + 1]);  // +1 across boundary c + 1
        CHECK(t.key[a][c + 1] + t.down[a][c + 1] == t.key[a][c]);  // -1 across the same boundary
      }
    }
  std::vector<std::int32_t> short_buffer(words.size() - 1);
  CHECK_THROWS_AS(CellKeyTables::build(g, b, short_buffer), std::invalid_argument);
}

TEST_CASE("cell order: a bricked walk visits the linear walk's cells, empty-space jumps included") {
  const Scene s = random_scene(21, 40, 4, 2, 0.05f);
  const Built built(s, forced(23, 17, 29));
  const Grid& grid = built.grid;
  const GridInfo& g = grid.info;
  const CellBricks b = choose_cell_bricks(g, 32);
  std::vector<std::int32_t> words(CellKeyTables::words(g));
  const CellKeyTables t = CellKeyTables::build(g, b, words);
  std::vector<std::uint32_t> key_of(g.cell_count());
  for (int z = 0; z < g.res[2]; ++z)
    for (int y = 0; y < g.res[1]; ++y)
      for (int x = 0; x < g.res[0]; ++x) key_of[g.cell_index(x, y, z)] = std::uint32_t(b.key(g, x, y, z));
  std::vector<std::uint32_t> cell_of(b.keys(g), ~0u);
  for (std::uint32_t c = 0; c < g.cell_count(); ++c) cell_of[key_of[c]] = c;

  Rng rng(5);
  const Bounds3 around = grown(g.bounds, 0.3f);
  std::size_t jumps = 0, cells = 0;
  for (int i = 0; i < 4000; ++i) {
    Vec3 d = random_unit(rng);
    if (i % 9 == 0) d = {0, 0, 0}, d[i % 3] = i % 2 ? 1.0f : -1.0f;  // axis-parallel
    const Ray ray{random_in(rng, i % 2 ? around : g.bounds), d, 0.0f, kInfinity};
    std::vector<std::uint32_t> linear, bricked;
    walk_grid(g, LinearCellOrder{}, ray, [&](std::uint32_t c, float) -> std::uint32_t {
      linear.push_back(c);
      return grid.empty_distance[c];
    });
    walk_grid(g, t, ray, [&](std::uint32_t k, float) -> std::uint32_t {
      REQUIRE(k < cell_of.size());
      const std::uint32_t c = cell_of[k];
      REQUIRE(c != ~0u);  // a key of a cell, not padding
      bricked.push_back(c);
      jumps += grid.empty_distance[c] >= kMinJumpDistance;
      return grid.empty_distance[c];
    });
    CHECK(bricked == linear);
    cells += linear.size();
  }
  CHECK(cells > 4000);
  CHECK(jumps > 100);
}
