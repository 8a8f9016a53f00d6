#include "core/cell_order.h"

#include <fmt/core.h>

#include <algorithm>
#include <limits>
#include <stdexcept>

namespace raynode::core {

CellBricks choose_cell_bricks(const GridInfo& g, std::int32_t slots) {
  if (slots < 1) throw std::invalid_argument(fmt::format("a directory brick needs at least one slot, got {}", slots));
  const double cells = double(g.res[0]) * double(g.res[1]) * double(g.res[2]);
  CellBricks best;
  best.slots = slots;
  double best_score = std::numeric_limits<double>::infinity();
  for (std::int32_t x = 1; x <= std::min(slots, g.res[0]); ++x)
    for (std::int32_t y = 1; y <= std::min(slots / x, g.res[1]); ++y) {
      // The deepest brick that fits: a shallower one only adds pages.
      const std::int32_t z = std::min(slots / (x * y), g.res[2]);
      CellBricks b;
      b.dims = {x, y, z};
      b.slots = slots;
      const double growth = double(b.keys(g)) / cells;
      const double score = (1.0 / x + 1.0 / y + 1.0 / z) * growth;
      if (score < best_score) best = b, best_score = score;  // first of equals: deterministic
    }
  return best;
}

CellKeyTables CellKeyTables::build(const GridInfo& g, const CellBricks& bricks, std::span<std::int32_t> buffer) {
  if (buffer.size() < words(g))
    throw std::invalid_argument(fmt::format("cell key tables need {} words, got {}", words(g), buffer.size()));
  if (bricks.keys(g) > std::uint64_t(std::numeric_limits<std::int32_t>::max()))
    throw std::length_error(fmt::format("a bricked directory of {} keys does not fit 31-bit keys", bricks.keys(g)));
  CellKeyTables t;
  std::int32_t* w = buffer.data();
  for (int a = 0; a < 3; ++a) {
    const std::int32_t res = g.res[a];
    std::int32_t* key = w;
    std::int32_t* up = key + res;
    std::int32_t* down = up + res + 1;
    w = down + res + 1;
    for (std::int32_t c = 0; c < res; ++c) key[c] = std::int32_t(bricks.axis_key(g, a, c));
    up[0] = down[0] = up[res] = down[res] = 0;
    for (std::int32_t b = 1; b < res; ++b) {
      up[b] = key[b] - key[b - 1];
      down[b] = -up[b];
    }
    t.key[a] = key;
    t.up[a] = up;
    t.down[a] = down;
  }
  return t;
}

}  // namespace raynode::core
