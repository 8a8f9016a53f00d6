#include "core/cost_model.h"

#include <algorithm>
#include <cmath>

namespace raynode::core {

const char* cost_feature_name(CostFeature f) {
  switch (f) {
    case CostFeature::kPrimaryRay: return "primary_ray";
    case CostFeature::kShadowRay: return "shadow_ray";
    case CostFeature::kReflectedRay: return "reflected_ray";
    case CostFeature::kRefractedRay: return "refracted_ray";
    case CostFeature::kCell: return "cell";
    case CostFeature::kEmptyJump: return "empty_jump";
    case CostFeature::kTriangleTest: return "triangle_test";
    case CostFeature::kSphereTest: return "sphere_test";
    case CostFeature::kConeTest: return "cone_test";
    case CostFeature::kMailboxSkip: return "mailbox_skip";
    case CostFeature::kPageAccess: return "page_access";
    case CostFeature::kLruUpdate: return "lru_update";
    case CostFeature::kPageFault: return "page_fault";
    case CostFeature::kCachePageAccess: return "cache_page_access";
    case CostFeature::kCount: break;
  }
  return "?";
}

CostCounts cost_counts(const RayCounts& rays, const TraversalStats& traversal) {
  CostCounts c{};
  auto at = [&c](CostFeature f) -> double& { return c[std::size_t(f)]; };
  at(CostFeature::kPrimaryRay) = double(rays.primary);
  at(CostFeature::kShadowRay) = double(rays.shadow);
  at(CostFeature::kReflectedRay) = double(rays.reflected);
  at(CostFeature::kRefractedRay) = double(rays.refracted);
  at(CostFeature::kCell) = double(traversal.cells_visited);
  at(CostFeature::kEmptyJump) = double(traversal.empty_jumps);
  at(CostFeature::kTriangleTest) = double(traversal.triangle_tests);
  at(CostFeature::kSphereTest) = double(traversal.sphere_tests);
  at(CostFeature::kConeTest) = double(traversal.cone_tests);
  at(CostFeature::kMailboxSkip) = double(traversal.mailbox_skips);
  return c;
}

CostModel fit_cost_model(std::span<const CostSample> samples, const std::array<bool, kCostFeatureCount>& fit,
                         const CostModel& start) {
  constexpr int K = kCostFeatureCount;
  // Weighted normal equations over the fitted features, columns scaled to
  // unit diagonal so that coordinate descent converges at one rate.
  std::array<std::array<double, K>, K> a{};
  std::array<double, K> b{};
  for (const CostSample& s : samples) {
    if (!(s.seconds > 0)) continue;
    double y = s.seconds;
    for (int k = 0; k < K; ++k)
      if (!fit[std::size_t(k)]) y -= start.unit_s[std::size_t(k)] * s.counts[std::size_t(k)];
    const double w = 1.0 / (s.seconds * s.seconds);
    for (int i = 0; i < K; ++i) {
      if (!fit[std::size_t(i)]) continue;
      b[std::size_t(i)] += w * s.counts[std::size_t(i)] * y;
      for (int j = 0; j < K; ++j)
        if (fit[std::size_t(j)]) a[std::size_t(i)][std::size_t(j)] += w * s.counts[std::size_t(i)] * s.counts[std::size_t(j)];
    }
  }
  std::array<double, K> scale{};
  for (int i = 0; i < K; ++i) scale[std::size_t(i)] = a[std::size_t(i)][std::size_t(i)] > 0 ? std::sqrt(a[std::size_t(i)][std::size_t(i)]) : 0.0;
  // x = c * scale: minimise 0.5 x'Ax - b'x with A, b scaled, x >= 0.
  std::array<double, K> x{};
  for (int i = 0; i < K; ++i)
    if (scale[std::size_t(i)] > 0) x[std::size_t(i)] = std::max(0.0, start.unit_s[std::size_t(i)]) * scale[std::size_t(i)];
  for (int sweep = 0; sweep < 5000; ++sweep) {
    double change = 0;
    for (int i = 0; i < K; ++i) {
      if (!fit[std::size_t(i)] || scale[std::size_t(i)] == 0) continue;
      double g = -b[std::size_t(i)] / scale[std::size_t(i)];
      for (int j = 0; j < K; ++j)
        if (fit[std::size_t(j)] && scale[std::size_t(j)] > 0)
          g += a[std::size_t(i)][std::size_t(j)] / (scale[std::size_t(i)] * scale[std::size_t(j)]) * x[std::size_t(j)];
      const double next = std::max(0.0, x[std::size_t(i)] - g);  // unit diagonal
      change = std::max(change, std::abs(next - x[std::size_t(i)]));
      x[std::size_t(i)] = next;
    }
    if (change < 1e-12) break;
  }
  CostModel m = start;
  for (int i = 0; i < K; ++i)
    if (fit[std::size_t(i)]) m.unit_s[std::size_t(i)] = scale[std::size_t(i)] > 0 ? x[std::size_t(i)] / scale[std::size_t(i)] : 0.0;
  return m;
}

}  // namespace raynode::core
