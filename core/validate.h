// Grid-versus-Embree validation: fires the same rays through the custom
// uniform grid and through Embree and counts disagreements.
//
// Place in the data flow: Database + Grid + EmbreeScene -> validate_grid ->
// ValidateReport -> `raynode validate` (text or JSON, exit 1 on mismatch).
//
// Ray sets (deterministic for a seed):
//  - primary: one ray through each pixel centre of the view (width x height);
//  - random: origins uniform in the scene box grown by 50%, half with
//    uniform random directions, half aimed at a random point of a random
//    primitive (so sparse scenes still get hits);
//  - secondary: from the grid's hit points of primary and random rays, a
//    mirror-reflected ray ("reflected") and a random-direction ray
//    ("scattered"), their origins spawned exactly as the tracer spawns its
//    secondary rays (spawn.h: the hit point's error bound, offset to the side
//    they leave towards), so that both structures see the rays the renderer
//    casts; also checked as any-hit (shadow) queries.
// Each set reports the worst relative t error |t_grid - t_embree| / max(t)
// over the rays where both hit within tolerance.
// Mismatch: one structure hits and the other misses, or both hit with t
// differing by more than tolerance = t_rel / max(|cos a|, 1e-4) x
// max(t_grid, t_embree) + 1e-6 x scene diagonal, where a is the angle between
// the ray and the hit surface's normal (a float t is ill-conditioned for
// grazing rays) (the primitive may differ when t agrees: shared edges),
// or the any-hit answers differ. Every disagreement is refereed by a
// brute-force closest hit over all primitives in double precision, computed
// twice, with triangles shrunk and grown by a relative barycentric margin of
// 1e-5 / max(|cos a|, 1e-4) (a ray that close to an edge, e.g. grazing a silhouette, may go
// either way in float) plus the barycentric error that the float test's
// rounding of the ray-space vertex coordinates can cause (it grows with the
// distance from the ray origin over the triangle's size: a small triangle
// seen from far away); the shrunk answer also leaves out hits within the
// rounding of the plane crossing (an origin spawned within rounding
// distance of a surface: the grid rejects those, as it must; Embree may
// not); when the grid's hit distance lies between the two
// referee answers, for the ray or for the ray tested in pieces in the grid's
// tracing frame as the grid tests it (closest_in_frame: a ray from beyond
// the frame is tested from its entry point rounded to float, which moves its
// line by up to half a float spacing of the frame's size, and a ray grazing
// a small sphere or cone that closely may go either way), it is counted as
// an oracle error (Embree's
// robust mode inflates triangles a little; its float sphere test loses
// digits on small, distant spheres), not as a mismatch.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/cell_blocks.h"
#include "core/database.h"
#include "core/embree_scene.h"
#include "core/grid.h"
#include "core/traverse.h"

namespace raynode::core {

struct ValidateParams {
  int width = 512;                  ///< primary rays: width x height
  int height = 512;
  std::size_t random_rays = 400000;
  std::uint64_t seed = 1;
  float t_rel = 1e-4f;              ///< relative t tolerance
  std::size_t max_examples = 10;    ///< mismatching rays kept for the report
  /// The grid's packed cells (cell_blocks.h) as sequential mode traces
  /// them: cells listing at least this many triangles; 0 = none (every
  /// cell walks its list, as the node modes do).
  std::uint32_t pack_min = kDefaultPackMin;
};

/// Counts for one ray set.
struct ValidateCounts {
  std::uint64_t rays = 0;
  std::uint64_t grid_hits = 0;
  std::uint64_t embree_hits = 0;
  std::uint64_t hit_vs_miss = 0;      ///< grid hit, Embree missed
  std::uint64_t miss_vs_hit = 0;      ///< grid missed, Embree hit
  std::uint64_t t_mismatch = 0;       ///< both hit, t beyond tolerance
  std::uint64_t other_primitive = 0;  ///< both hit, different primitive, t within tolerance (not a mismatch)
  std::uint64_t any_hit_mismatch = 0; ///< shadow-query disagreements
  /// Disagreements where the double-precision referee sided with the grid
  /// (Embree's error; not counted as mismatches).
  std::uint64_t oracle_errors = 0;
  double max_t_rel_error = 0.0;       ///< largest |t_g - t_e| / max(t) where both hit
  std::uint64_t mismatches() const { return hit_vs_miss + miss_vs_hit + t_mismatch + any_hit_mismatch; }
  ValidateCounts& operator+=(const ValidateCounts& o);
};

/// One disagreeing ray, for diagnosis.
struct MismatchExample {
  std::string set;
  Ray ray;
  Hit grid, embree;
};

struct ValidateReport {
  ValidateCounts primary, random;
  ValidateCounts reflected, scattered;  ///< the two kinds of secondary ray
  ValidateCounts secondary;             ///< reflected + scattered
  ValidateCounts total;
  std::vector<MismatchExample> examples;
  TraversalStats grid_stats;
};

/// Runs the validation. The view is used for primary rays if the database
/// has one (otherwise a view looking at the scene box from outside).
ValidateReport validate_grid(const Database& db, const Grid& grid, const EmbreeScene& embree,
                             const ValidateParams& params = {});

}  // namespace raynode::core
