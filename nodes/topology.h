// The interconnection network's shape: which nodes are neighbours and how
// many hops a message travels (docs/architecture.md, "Topology"). The iPSC/2 of the
// paper is a hypercube; ring and 2D torus are there for comparison.
//
// Place in the data flow: Machine owns one Topology; the network model
// (network.h) charges hops(a, b) x per-hop cost; work distribution (work.h)
// sends work requests along ring_next(), the ring embedded in the topology so
// that consecutive ring members are neighbours (a Gray code on the
// hypercube, a snake on the torus).
//
// Routing is minimal: hops = ring distance (ring), Hamming distance of the
// ids (hypercube; e-cube routing), wrap-around Manhattan distance (torus).
// The host is attached to node 0's corner of the network: a host message
// travels 1 hop. A hypercube whose node count is not a power of two is the
// incomplete hypercube of the ids 0..N-1 (hops still = Hamming distance).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "nodes/arena.h"

namespace raynode::nodes {

enum class TopologyKind { kRing, kHypercube, kTorus2D };

/// "ring", "hypercube", "torus"; throws std::invalid_argument otherwise.
TopologyKind parse_topology(const std::string& name);
const char* topology_name(TopologyKind kind);

class Topology {
 public:
  /// nodes >= 1; throws std::invalid_argument otherwise.
  Topology(TopologyKind kind, std::uint32_t nodes);

  TopologyKind kind() const { return kind_; }
  std::uint32_t nodes() const { return nodes_; }
  /// Torus shape: rows x cols = nodes, rows <= cols, as square as N allows.
  std::uint32_t rows() const { return rows_; }
  std::uint32_t cols() const { return cols_; }

  /// Links a message crosses from a to b (0 when a == b; 1 to or from kHost).
  std::uint32_t hops(NodeId a, NodeId b) const;
  /// Direct neighbours of `node`, ascending, without duplicates.
  std::vector<NodeId> neighbours(NodeId node) const;
  /// Largest hop count between two nodes.
  std::uint32_t diameter() const;

  /// The embedded ring: successor and predecessor of `node` (itself when N = 1).
  NodeId ring_next(NodeId node) const { return ring_order_[(ring_pos_[node] + 1) % nodes_]; }
  NodeId ring_prev(NodeId node) const { return ring_order_[(ring_pos_[node] + nodes_ - 1) % nodes_]; }
  /// Position of `node` on the ring, 0..N-1, and the node at a position.
  std::uint32_t ring_position(NodeId node) const { return ring_pos_[node]; }
  NodeId ring_node(std::uint32_t position) const { return ring_order_[position]; }

 private:
  TopologyKind kind_;
  std::uint32_t nodes_;
  std::uint32_t rows_ = 1, cols_ = 1;
  std::vector<NodeId> ring_order_;
  std::vector<std::uint32_t> ring_pos_;
};

}  // namespace raynode::nodes
