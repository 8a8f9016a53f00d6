// apps/node_runs.h: median(), the middle of `bench nodes`' one-node pairs.
#include "apps/node_runs.h"

#include <doctest/doctest.h>

#include <cmath>
#include <vector>

using raynode::apps::median;

TEST_CASE("median: odd and even counts, any order, the caller's order kept") {
  CHECK(median({3.0}) == 3.0);
  std::vector<double> odd{5.0, 1.0, 4.0, 2.0, 3.0};
  CHECK(median(odd) == 3.0);
  CHECK(odd == std::vector<double>{5.0, 1.0, 4.0, 2.0, 3.0});  // taken by copy
  CHECK(median({4.0, 1.0, 3.0, 2.0}) == 2.5);                  // mean of the middle two
  CHECK(median({1.0, 1.0, 10.0, 10.0}) == 5.5);
  CHECK(median({2.0, 2.0, 2.0, 9.0}) == 2.0);                  // ties in the lower half
  CHECK(median({1.20, 0.94, 1.19, 1.18, 1.21}) == doctest::Approx(1.19));  // an outlier pair does not move it
}

TEST_CASE("median: none is NaN") { CHECK(std::isnan(median({}))); }
