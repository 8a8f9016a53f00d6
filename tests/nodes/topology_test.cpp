#include <doctest/doctest.h>

#include <algorithm>
#include <set>

#include "nodes/topology.h"

using namespace raynode::nodes;

TEST_CASE("topology: hop counts are a metric and neighbours are one hop away") {
  for (TopologyKind kind : {TopologyKind::kRing, TopologyKind::kHypercube, TopologyKind::kTorus2D})
    for (std::uint32_t n : {1u, 2u, 3u, 4u, 7u, 12u, 16u, 64u}) {
      const Topology t(kind, n);
      CAPTURE(topology_name(kind));
      CAPTURE(n);
      for (NodeId a = 0; a < n; ++a) {
        CHECK(t.hops(a, a) == 0);
        CHECK(t.hops(a, kHost) == 1);
        for (NodeId b = 0; b < n; ++b) {
          CHECK(t.hops(a, b) == t.hops(b, a));
          CHECK(t.hops(a, b) <= t.diameter());
          if (a != b) CHECK(t.hops(a, b) >= 1);
        }
        for (NodeId b : t.neighbours(a)) CHECK(t.hops(a, b) == 1);
      }
    }
}

TEST_CASE("topology: known shapes — 16-node hypercube, 4x4 torus, 16-node ring") {
  const Topology cube(TopologyKind::kHypercube, 16);
  CHECK(cube.hops(0, 15) == 4);
  CHECK(cube.hops(5, 6) == 2);
  CHECK(cube.neighbours(0) == std::vector<NodeId>{1, 2, 4, 8});
  CHECK(cube.diameter() == 4);
  const Topology torus(TopologyKind::kTorus2D, 16);
  CHECK(torus.rows() == 4);
  CHECK(torus.cols() == 4);
  CHECK(torus.hops(0, 15) == 2);  // (0,0) -> (3,3) wraps both ways
  CHECK(torus.hops(0, 10) == 4);  // (0,0) -> (2,2)
  CHECK(torus.neighbours(5) == std::vector<NodeId>{1, 4, 6, 9});
  const Topology ring(TopologyKind::kRing, 16);
  CHECK(ring.hops(0, 8) == 8);
  CHECK(ring.hops(1, 15) == 2);
  const Topology prime(TopologyKind::kTorus2D, 7);
  CHECK(prime.rows() == 1);
  CHECK(prime.cols() == 7);
}

TEST_CASE("topology: the embedded ring visits every node once and steps between neighbours") {
  for (TopologyKind kind : {TopologyKind::kRing, TopologyKind::kHypercube, TopologyKind::kTorus2D})
    for (std::uint32_t n : {1u, 2u, 4u, 8u, 16u, 64u, 256u}) {
      const Topology t(kind, n);
      CAPTURE(topology_name(kind));
      CAPTURE(n);
      std::set<NodeId> seen;
      NodeId node = 0;
      for (std::uint32_t i = 0; i < n; ++i) {
        seen.insert(node);
        const NodeId next = t.ring_next(node);
        CHECK(t.ring_prev(next) == node);
        if (n > 1) CHECK(t.hops(node, next) == 1);  // true for full hypercubes and even-row tori
        node = next;
      }
      CHECK(node == 0);
      CHECK(seen.size() == n);
    }
}

TEST_CASE("topology: bad names and zero nodes are refused") {
  CHECK_THROWS_AS(parse_topology("mesh"), std::invalid_argument);
  CHECK(parse_topology("torus") == TopologyKind::kTorus2D);
  CHECK_THROWS_AS(Topology(TopologyKind::kRing, 0), std::invalid_argument);
}
