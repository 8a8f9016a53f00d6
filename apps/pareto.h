// The Pareto front of a set of measured points with two costs to minimise
// (e.g. render time in seconds and image error): the points that no other
// point beats in both. Used by `raynode bench quality` to mark the settings
// worth having; pure and header-only so that tests link nothing else.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace raynode::apps {

/// One measured point: two costs, both to be minimised (any units).
struct CostPoint {
  double x = 0;  ///< first cost, e.g. wall seconds
  double y = 0;  ///< second cost, e.g. RMSE
};

/// Indices of the Pareto-optimal points of `points`, in order of increasing
/// x (ties: increasing y, then increasing index), so that joining them gives
/// the front's staircase (y never increases along it).
///
/// Point i is on the front iff no point j dominates it, i.e. no j has
/// x_j <= x_i and y_j <= y_i with at least one of them strict. Exact
/// duplicates do not dominate each other: all copies of a front point are
/// returned. Points with a NaN cost are never on the front and never
/// dominate; +inf is an ordinary (worst) value. O(n log n); pure, thread-safe.
inline std::vector<std::size_t> pareto_front(const std::vector<CostPoint>& points) {
  std::vector<std::size_t> order;
  order.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    if (!std::isnan(points[i].x) && !std::isnan(points[i].y)) order.push_back(i);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    if (points[a].x != points[b].x) return points[a].x < points[b].x;
    if (points[a].y != points[b].y) return points[a].y < points[b].y;
    return a < b;
  });
  // Sweep by increasing x: a point is on the front iff its y is below the
  // best y of every point with a strictly smaller x, or, within a group of
  // equal x, it has the group's smallest y (and that beats earlier groups).
  std::vector<std::size_t> front;
  double best_y = INFINITY;       // smallest y over groups with smaller x
  bool have_best = false;
  for (std::size_t k = 0; k < order.size();) {
    std::size_t end = k;
    while (end < order.size() && points[order[end]].x == points[order[k]].x) ++end;
    const double group_min = points[order[k]].y;  // sorted by y within the group
    if (!have_best || group_min < best_y) {
      for (std::size_t m = k; m < end && points[order[m]].y == group_min; ++m) front.push_back(order[m]);
      best_y = group_min;
      have_best = true;
    }
    k = end;
  }
  return front;
}

}  // namespace raynode::apps
