// Adaptive grid parameters that give the small scenes of the test suites
// sub-grids, which the defaults (sized for real scenes) would not build.
#pragma once

#include <cstdint>

#include "core/grid.h"

namespace raynode::testing {

/// The adaptive grid refining every cell weighing at least `sub_grid_min`
/// (GridParams::sub_grid_min's units: a listed triangle 1, a cone 4) where
/// a ray crossing it would meet no more references in the sub-grid than in
/// the leaf (sub_grid_walk_share 1, the cost model's
/// loosest bound). `coarse_top`: a top grid of 1/16 cell per primitive, so
/// that sub-grids nest two levels deep even on scenes of a few hundred
/// primitives.
inline core::GridParams small_scene_sub_grids(float sub_grid_min, bool coarse_top) {
  core::GridParams p;
  p.kind = core::GridKind::kAdaptive;
  if (coarse_top) p.top_density = 1.0f / 16.0f;
  p.sub_grid_min = sub_grid_min;
  p.sub_grid_walk_share = 1.0;
  return p;
}

}  // namespace raynode::testing
