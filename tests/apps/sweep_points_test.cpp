// apps/sweep_points.h: the node, page-size and cache lists of `raynode sweep`.
#include "apps/sweep_points.h"

#include <doctest/doctest.h>

#include <cmath>
#include <string>
#include <vector>

#include "apps/commands.h"

using raynode::apps::CachePoint;
using raynode::apps::parse_cache_points;
using raynode::apps::parse_count_list;
using raynode::apps::parse_node_list;
using raynode::apps::UsageError;
using Counts = std::vector<std::uint32_t>;

namespace {

std::vector<std::string> labels(const std::vector<CachePoint>& points) {
  std::vector<std::string> out;
  for (const CachePoint& p : points) out.push_back(p.label);
  return out;
}

}  // namespace

TEST_CASE("sweep points: a node range is the powers of two between its ends, ends included") {
  CHECK(parse_node_list("1..64") == Counts{1, 2, 4, 8, 16, 32, 64});
  CHECK(parse_node_list("3..20") == Counts{3, 4, 8, 16, 20});
  CHECK(parse_node_list("16..16") == Counts{16});
}

TEST_CASE("sweep points: node lists are sorted and lose duplicates, items and ranges mix") {
  CHECK(parse_node_list("8, 1,8,2") == Counts{1, 2, 8});
  CHECK(parse_node_list("1,3..16") == Counts{1, 3, 4, 8, 16});
  CHECK(parse_count_list("256..4096", "--page-size", 64, 1u << 24) == Counts{256, 512, 1024, 2048, 4096});
}

TEST_CASE("sweep points: an empty node list, 0, junk, a backwards range or too many nodes are usage errors") {
  for (const char* bad : {"", " ", ",", "0", "1,0", "00", "1,,2", "x", "1.5", "-2", "64..2", "5000", "1..5000", "2.."})
    CHECK_THROWS_AS_MESSAGE(parse_node_list(bad), UsageError, "'", bad, "'");
  CHECK_THROWS_WITH_AS(parse_node_list("0,2"), "--nodes: a machine needs at least 1 node, got 0", UsageError);
  CHECK_THROWS_WITH_AS(parse_node_list(""), doctest::Contains("the list is empty"), UsageError);
}

TEST_CASE("sweep points: a cache range A..B% is A, the 1-2-5 series strictly inside, and B") {
  const std::vector<CachePoint> p = parse_cache_points("1..100%");
  CHECK(labels(p) == std::vector<std::string>{"1%", "2%", "5%", "10%", "20%", "50%", "100%"});
  for (const CachePoint& c : p) {
    CHECK(c.pages == 0);
    CHECK_FALSE(c.max);
  }
  CHECK(p[2].fraction == doctest::Approx(0.05));
  CHECK(p.back().fraction == doctest::Approx(1.0));
  CHECK(labels(parse_cache_points("0.1..10")) ==
        std::vector<std::string>{"0.1%", "0.2%", "0.5%", "1%", "2%", "5%", "10%"});
  CHECK(labels(parse_cache_points("3..70%")) == std::vector<std::string>{"3%", "5%", "10%", "20%", "50%", "70%"});
}

TEST_CASE("sweep points: A..B:N% gives N evenly spaced cache sizes") {
  const std::vector<CachePoint> p = parse_cache_points("5..70:3%");
  REQUIRE(p.size() == 3);
  CHECK(p[0].fraction == doctest::Approx(0.05));
  CHECK(p[1].fraction == doctest::Approx(0.375));
  CHECK(p[2].fraction == doctest::Approx(0.70));
}

TEST_CASE("sweep points: a trailing % applies to bare numbers, pages, max and repeats") {
  const std::vector<CachePoint> p = parse_cache_points("1,2,5%,204p,max,5");
  CHECK(labels(p) == std::vector<std::string>{"1%", "2%", "5%", "204p", "max"});
  CHECK(p[0].fraction == doctest::Approx(0.01));
  CHECK(p[3].pages == 204);
  CHECK(p[3].fraction == 0);
  CHECK(p[4].max);
  CHECK(p[4].fraction == 0);
  CHECK(p[4].pages == 0);
}

TEST_CASE("sweep points: bad cache sizes are usage errors naming the option") {
  for (const char* bad : {"", ",", "0", "0%", "101", "-5%", "abc", "nan", "5..1%", "1..5:1%", "1..5:x%", "0.5p",
                          "0p", "1,,2", "1..200%"})
    CHECK_THROWS_AS_MESSAGE(parse_cache_points(bad), UsageError, "'", bad, "'");
  CHECK_THROWS_WITH_AS(parse_cache_points("150", "--cache"),
                       doctest::Contains("--cache: a percentage must be in (0, 100]"), UsageError);
}
