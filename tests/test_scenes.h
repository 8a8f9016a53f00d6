// Helpers shared by the test suites: a small SPD database with its grid,
// and byte-exact image comparison.
#pragma once

#include <cstring>

#include "core/database.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/spd.h"

namespace raynode::testing {

struct BuiltScene {
  core::Database db;
  core::Grid grid;
};

inline BuiltScene build_spd(const char* name, int size, int tessellate = 0) {
  BuiltScene b;
  b.db = core::make_database(core::make_spd_scene(core::SpdParams{name, size, tessellate}));
  b.grid = core::build_grid(b.db);
  return b;
}

inline bool same_bytes(const core::Image& a, const core::Image& b) {
  return a.width == b.width && a.height == b.height && a.channels == b.channels &&
         std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * sizeof(float)) == 0;
}

}  // namespace raynode::testing
