// apps/pareto.h: the Pareto front that `raynode bench quality` draws.
#include "apps/pareto.h"

#include <doctest/doctest.h>

#include <cmath>
#include <vector>

using raynode::apps::CostPoint;
using raynode::apps::pareto_front;

namespace {

/// Brute force: i is on the front iff no j dominates it.
bool dominated(const std::vector<CostPoint>& p, std::size_t i) {
  for (std::size_t j = 0; j < p.size(); ++j)
    if (p[j].x <= p[i].x && p[j].y <= p[i].y && (p[j].x < p[i].x || p[j].y < p[i].y)) return true;
  return false;
}

}  // namespace

TEST_CASE("pareto: dominated points are dropped and the front comes back by increasing time") {
  // time, error
  const std::vector<CostPoint> p = {{3.0, 0.1}, {1.0, 0.5}, {2.0, 0.6}, {2.0, 0.2}, {4.0, 0.1}, {5.0, 0.01}};
  // {2,0.6} is beaten by {2,0.2} (same time, less error) and by {1,0.5};
  // {4,0.1} is beaten by {3,0.1} (same error, less time).
  CHECK(pareto_front(p) == std::vector<std::size_t>{1, 3, 0, 5});
}

TEST_CASE("pareto: the error never increases along the front (a staircase)") {
  std::vector<CostPoint> p;
  unsigned s = 12345;
  auto next = [&] {
    s = s * 1103515245u + 12345u;
    return double((s >> 8) % 1000) / 100.0;  // coarse values: many ties
  };
  for (int i = 0; i < 300; ++i) p.push_back({next(), next()});
  const std::vector<std::size_t> front = pareto_front(p);
  REQUIRE(!front.empty());
  for (std::size_t k = 1; k < front.size(); ++k) {
    CHECK(p[front[k]].x >= p[front[k - 1]].x);
    CHECK(p[front[k]].y <= p[front[k - 1]].y);
  }
  // Exactly the non-dominated points, as a brute force finds them.
  std::vector<bool> on(p.size(), false);
  for (std::size_t i : front) on[i] = true;
  for (std::size_t i = 0; i < p.size(); ++i) CHECK_MESSAGE(on[i] == !dominated(p, i), "point ", i);
}

TEST_CASE("pareto: exact duplicates of a front point are all on the front") {
  const std::vector<CostPoint> p = {{1.0, 1.0}, {1.0, 1.0}, {2.0, 2.0}};
  CHECK(pareto_front(p) == std::vector<std::size_t>{0, 1});
}

TEST_CASE("pareto: NaN costs are never on the front, infinite error counts as worst") {
  const std::vector<CostPoint> p = {{1.0, NAN}, {NAN, 0.0}, {2.0, INFINITY}, {3.0, 0.5}, {4.0, INFINITY}};
  // {2, inf} is the fastest valid point, so nothing dominates it; {4, inf} is dominated.
  CHECK(pareto_front(p) == std::vector<std::size_t>{2, 3});
  CHECK(pareto_front({}).empty());
  CHECK(pareto_front({{1.0, NAN}}).empty());
}

TEST_CASE("pareto: a single point and a zero error are handled") {
  CHECK(pareto_front({{0.5, 0.25}}) == std::vector<std::size_t>{0});
  const std::vector<CostPoint> p = {{1.0, 0.3}, {9.0, 0.0}, {10.0, 0.0}};
  CHECK(pareto_front(p) == std::vector<std::size_t>{0, 1});
}
