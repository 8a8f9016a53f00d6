// A cost model of the tracer's work: modelled seconds = operation counts x
// unit costs. It is the emulator's optional compute clock (`--clock model`,
// nodes/node.h "Virtual time"): a node's clock then advances by the modelled
// cost of the rays it traced instead of its thread's CPU time.
//
// Why: with 64 node threads on 2 cores, a node's CPU time also holds the
// refill of its private caches after every thread switch (each node works on
// its own copy or its own cached pages), which a real machine of 64 nodes
// with 64 caches never pays; measured, it adds ~50% to the summed busy time
// of a replicated render at 64 nodes. The counts do not depend on the host's
// load, so the model clock also makes virtual times repeatable on a noisy
// machine.
//
// The unit costs are fitted (non-negative least squares, relative error) to
// the single-thread CPU time of 8x8-pixel tiles of several SPD scenes on the
// machine named in kCostModelSource; `raynode bench cost-model` refits them
// and prints the fit. Seconds are this machine's seconds: the ipsc2 network
// preset scales to the model's own seconds per ray, so ratios of page
// transfer to ray computation stay the paper's.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>

#include "core/shade.h"
#include "core/traverse.h"

namespace raynode::core {

/// The counted operations, in CostModel's order.
enum class CostFeature : int {
  kPrimaryRay,    ///< camera ray made and traced (pixel bookkeeping included)
  kShadowRay,     ///< shadow ray (one per light and shaded hit that faces it)
  kReflectedRay,  ///< reflected ray spawned
  kRefractedRay,  ///< refracted (or totally internally reflected) ray spawned
  kCell,          ///< grid cell visited by the 3D-DDA
  kEmptyJump,     ///< empty-space jump of the 3D-DDA (TraversalStats::empty_jumps)
  kTriangleTest,  ///< ray/triangle test (watertight)
  kSphereTest,    ///< ray/sphere test
  kConeTest,      ///< ray/cone test
  kMailboxSkip,   ///< test avoided by the per-ray mailbox
  kPageAccess,    ///< svm: object access through the page table
  kLruUpdate,     ///< svm: LRU stamp given (svm::PagerStats::lru_updates: a cached page's first access in a pixel once the cache is full)
  kPageFault,     ///< svm: local work of a page fault (victim, frame copy, table); modelled, not fitted
  kCachePageAccess,  ///< svm: access to a page held in the cache, not a home page (svm::PagerStats::cache_page_accesses); priced by a machine description only
  kCount
};
inline constexpr int kCostFeatureCount = int(CostFeature::kCount);

/// Operation counts of some work (a node's, a tile's).
using CostCounts = std::array<double, kCostFeatureCount>;

/// The feature names, for tables and JSON ("primary_ray", ...).
const char* cost_feature_name(CostFeature f);

/// Counts of the tracer's operations in `rays` and `traversal`.
CostCounts cost_counts(const RayCounts& rays, const TraversalStats& traversal);

/// Seconds per operation, one per CostFeature; all >= 0.
struct CostModel {
  std::array<double, kCostFeatureCount> unit_s{};

  /// Modelled seconds of `counts`.
  double seconds(const CostCounts& counts) const {
    double s = 0;
    for (int i = 0; i < kCostFeatureCount; ++i) s += unit_s[std::size_t(i)] * counts[std::size_t(i)];
    return s;
  }
  /// Modelled seconds of a tracer's work (no pager terms).
  double seconds(const RayCounts& rays, const TraversalStats& traversal) const {
    return seconds(cost_counts(rays, traversal));
  }
};

/// Where and how the built-in model was fitted.
inline constexpr const char* kCostModelSource =
    "raynode bench cost-model, 2026-11-21, 2-core Intel Xeon VM (the CI kind): 128x128, 8x8-pixel tiles of "
    "teapot:8, mount:6, rings:4, rings:4 -t 1, tetra:8, balls:3; per-scene totals within 6% of CPU time; "
    "pager costs refitted 2026-11-21 on svm tiles (256x256, --repeat 5, median of 4 fits) after the pager's "
    "single access path";

/// The built-in model (fitted as kCostModelSource says; `raynode bench
/// cost-model` prints a refit in this form). Header-only, so that nodes/
/// code built without core (the TSan test) can use MachineParams.
inline CostModel default_cost_model() {
  CostModel m;
  auto at = [&m](CostFeature f) -> double& { return m.unit_s[std::size_t(f)]; };
  at(CostFeature::kPrimaryRay) = 30.57e-9;
  at(CostFeature::kShadowRay) = 19.29e-9;
  at(CostFeature::kReflectedRay) = 320e-9;
  at(CostFeature::kRefractedRay) = 29.35e-9;
  at(CostFeature::kCell) = 6.24e-9;
  // Fitted 2026-11-22 with the other tracer units held (`bench cost-model
  // --fit empty_jump --no-pager --width 256 --height 256 --repeat 5`):
  // 31-57 ns over three runs on a noisy machine (jumps from distance 2 up);
  // full refits gave 36-39 ns.
  at(CostFeature::kEmptyJump) = 40e-9;
  at(CostFeature::kTriangleTest) = 6.482e-9;
  at(CostFeature::kSphereTest) = 6.645e-9;
  at(CostFeature::kConeTest) = 28.19e-9;
  at(CostFeature::kMailboxSkip) = 7.387e-9;
  // Fits ranged 3.3-4.6 ns (page access) and 0-2.8 ns (cache access, now
  // an LRU update): the two counts move together, so the split is loose;
  // their sum is not.
  at(CostFeature::kPageAccess) = 3.5e-9;
  at(CostFeature::kLruUpdate) = 2.5e-9;
  // Modelled, not fitted: the local work of a fault (pick the victim, copy
  // a 1 KiB page into its frame, update the table) ~ 0.15 us. The CPU time
  // of a fault in an emulated run (~2.6 us fitted) is mostly the emulator's
  // thread wake-up and cold caches, which no real node pays. The ipsc2
  // network replaces it with the iPSC/2's figure, scaled
  // (nodes::NetworkModel::fault_s).
  at(CostFeature::kPageFault) = 150e-9;
  // Not fitted, 0 here: on this host a cached page's access costs what any
  // page access does (kPageAccess). A machine whose software shared memory
  // pays more for it says so (nodes::NetworkModel::cache_access_s, which
  // replaces this figure).
  at(CostFeature::kCachePageAccess) = 0;
  return m;
}

/// One calibration sample: measured seconds of some work and its counts.
struct CostSample {
  double seconds = 0;
  CostCounts counts{};
};

/// Non-negative least squares of sample seconds on counts, each sample
/// weighted by 1/seconds (so the fit minimises relative error). Only the
/// features in `fit` are fitted; the others keep `start`'s unit costs and
/// are subtracted from the samples first. Lawson-Hanson-free coordinate
/// descent: a few hundred sweeps over <= 12 unknowns.
CostModel fit_cost_model(std::span<const CostSample> samples, const std::array<bool, kCostFeatureCount>& fit,
                         const CostModel& start = {});

}  // namespace raynode::core
