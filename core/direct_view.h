// DirectView: the database view over plain in-memory arrays (Database +
// Grid). Used by sequential, shared and replicated modes (DESIGN.md, "One
// tracer, several data views"). Cheap to copy; refers to, does not own,
// the database and grid, which must outlive it.
#pragma once

#include <cstdint>

#include "core/database.h"
#include "core/grid.h"

namespace raynode::core {

class DirectView {
 public:
  DirectView(const Database& db, const Grid& grid) : db_(&db), grid_(&grid) {}

  const GridInfo& grid_info() const { return grid_->info; }
  template <class F>
  void for_each_in_cell(std::uint32_t cell, F&& f) const {
    const std::uint32_t* p = grid_->cell_primitives.data();
    for (std::uint32_t i = grid_->cell_start[cell], e = grid_->cell_start[cell + 1]; i < e; ++i) f(p[i]);
  }
  const Primitive& primitive(std::uint32_t id) const { return db_->primitives[id]; }
  const Material& material(std::uint32_t id) const { return db_->materials[id]; }
  const Database& database() const { return *db_; }

 private:
  const Database* db_;
  const Grid* grid_;
};

}  // namespace raynode::core
