#include <doctest/doctest.h>

#include <cmath>
#include <vector>

#include "core/cost_model.h"
#include "test_random.h"

using namespace raynode::core;

namespace {

CostModel known_model() {
  CostModel m;
  for (int k = 0; k < kCostFeatureCount; ++k) m.unit_s[std::size_t(k)] = 1e-9 * double(k + 1);
  m.unit_s[std::size_t(CostFeature::kMailboxSkip)] = 0;  // a zero cost must come back as zero
  return m;
}

std::vector<CostSample> samples_of(const CostModel& truth, int count) {
  raynode::testing::Rng rng(7);
  std::vector<CostSample> out;
  for (int i = 0; i < count; ++i) {
    CostSample s;
    for (int k = 0; k < kCostFeatureCount; ++k) s.counts[std::size_t(k)] = std::floor(double(raynode::testing::uniform(rng, 0.0f, 1000.0f)));
    s.seconds = truth.seconds(s.counts);
    out.push_back(s);
  }
  return out;
}

}  // namespace

TEST_CASE("cost model: the fit recovers known unit costs from exact samples") {
  const CostModel truth = known_model();
  const std::vector<CostSample> samples = samples_of(truth, 400);
  std::array<bool, kCostFeatureCount> all{};
  all.fill(true);
  const CostModel fitted = fit_cost_model(samples, all);
  for (int k = 0; k < kCostFeatureCount; ++k) {
    CAPTURE(cost_feature_name(CostFeature(k)));
    CHECK(fitted.unit_s[std::size_t(k)] == doctest::Approx(truth.unit_s[std::size_t(k)]).epsilon(1e-4).scale(1e-9));
  }
}

TEST_CASE("cost model: features not fitted keep the start's costs and are taken out of the samples first") {
  const CostModel truth = known_model();
  const std::vector<CostSample> samples = samples_of(truth, 400);
  std::array<bool, kCostFeatureCount> pager_only{};
  for (int k = int(CostFeature::kPageAccess); k < kCostFeatureCount; ++k) pager_only[std::size_t(k)] = true;
  CostModel start = truth;
  for (int k = int(CostFeature::kPageAccess); k < kCostFeatureCount; ++k) start.unit_s[std::size_t(k)] = 0;
  const CostModel fitted = fit_cost_model(samples, pager_only, start);
  for (int k = 0; k < kCostFeatureCount; ++k)
    CHECK(fitted.unit_s[std::size_t(k)] == doctest::Approx(truth.unit_s[std::size_t(k)]).epsilon(1e-4).scale(1e-9));
}

TEST_CASE("cost model: costs stay non-negative when the data would pull one below zero") {
  // seconds = 2 x count0 - 1 x count1 cannot be met with costs >= 0.
  std::vector<CostSample> samples;
  for (int i = 1; i <= 50; ++i) {
    CostSample s;
    s.counts[0] = double(i);
    s.counts[1] = double(i % 7);
    s.seconds = 2e-9 * s.counts[0] - 1e-9 * s.counts[1];  // > 0: count1 <= count0
    samples.push_back(s);
  }
  std::array<bool, kCostFeatureCount> two{};
  two[0] = two[1] = true;
  const CostModel fitted = fit_cost_model(samples, two);
  CHECK(fitted.unit_s[0] > 0);
  CHECK(fitted.unit_s[1] == 0);
}

TEST_CASE("cost model: seconds are the counts weighted by the unit costs, the built-in model is non-negative") {
  RayCounts rays;
  rays.primary = 10;
  rays.shadow = 4;
  TraversalStats t;
  t.cells_visited = 100;
  t.triangle_tests = 30;
  const CostModel m = known_model();
  auto unit = [&](CostFeature f) { return m.unit_s[std::size_t(f)]; };
  const double expected = 10 * unit(CostFeature::kPrimaryRay) + 4 * unit(CostFeature::kShadowRay) +
                          100 * unit(CostFeature::kCell) + 30 * unit(CostFeature::kTriangleTest);
  CHECK(expected > 0);
  CHECK(m.seconds(rays, t) == doctest::Approx(expected).epsilon(1e-12));
  for (double u : default_cost_model().unit_s) CHECK(u >= 0);
  CHECK(default_cost_model().unit_s[std::size_t(CostFeature::kPrimaryRay)] > 0);
}
