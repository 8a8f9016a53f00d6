#include "nodes/topology.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <stdexcept>

namespace raynode::nodes {

TopologyKind parse_topology(const std::string& name) {
  if (name == "ring") return TopologyKind::kRing;
  if (name == "hypercube") return TopologyKind::kHypercube;
  if (name == "torus") return TopologyKind::kTorus2D;
  throw std::invalid_argument("unknown topology '" + name + "' (ring, hypercube, torus)");
}

const char* topology_name(TopologyKind kind) {
  switch (kind) {
    case TopologyKind::kRing: return "ring";
    case TopologyKind::kHypercube: return "hypercube";
    case TopologyKind::kTorus2D: return "torus";
  }
  return "?";
}

Topology::Topology(TopologyKind kind, std::uint32_t nodes) : kind_(kind), nodes_(nodes) {
  if (nodes < 1) throw std::invalid_argument("a machine needs at least one node");
  if (kind == TopologyKind::kTorus2D) {
    rows_ = std::uint32_t(std::sqrt(double(nodes)));
    while (nodes % rows_ != 0) --rows_;
    cols_ = nodes / rows_;
  }
  ring_order_.reserve(nodes);
  switch (kind) {
    case TopologyKind::kRing:
      for (std::uint32_t i = 0; i < nodes; ++i) ring_order_.push_back(i);
      break;
    case TopologyKind::kHypercube: {
      // Reflected Gray code: consecutive codes differ in one bit, so
      // consecutive ring members are hypercube neighbours.
      const std::uint32_t full = std::bit_ceil(nodes);
      for (std::uint32_t i = 0; i < full; ++i) {
        const std::uint32_t g = i ^ (i >> 1);
        if (g < nodes) ring_order_.push_back(g);
      }
      break;
    }
    case TopologyKind::kTorus2D:
      // Snake (boustrophedon) order over the rows.
      for (std::uint32_t r = 0; r < rows_; ++r)
        for (std::uint32_t k = 0; k < cols_; ++k) ring_order_.push_back(r * cols_ + (r % 2 == 0 ? k : cols_ - 1 - k));
      break;
  }
  ring_pos_.assign(nodes, 0);
  for (std::uint32_t p = 0; p < nodes; ++p) ring_pos_[ring_order_[p]] = p;
}

std::uint32_t Topology::hops(NodeId a, NodeId b) const {
  if (a == b) return 0;
  if (a == kHost || b == kHost) return 1;
  switch (kind_) {
    case TopologyKind::kRing: {
      const std::uint32_t d = a > b ? a - b : b - a;
      return std::min(d, nodes_ - d);
    }
    case TopologyKind::kHypercube: return std::uint32_t(std::popcount(a ^ b));
    case TopologyKind::kTorus2D: {
      const std::uint32_t ra = a / cols_, ca = a % cols_, rb = b / cols_, cb = b % cols_;
      const std::uint32_t dr = ra > rb ? ra - rb : rb - ra, dc = ca > cb ? ca - cb : cb - ca;
      return std::min(dr, rows_ - dr) + std::min(dc, cols_ - dc);
    }
  }
  return 0;
}

std::vector<NodeId> Topology::neighbours(NodeId node) const {
  std::vector<NodeId> out;
  switch (kind_) {
    case TopologyKind::kRing:
      if (nodes_ > 1) out = {(node + 1) % nodes_, (node + nodes_ - 1) % nodes_};
      break;
    case TopologyKind::kHypercube:
      for (std::uint32_t bit = 1; bit < std::bit_ceil(nodes_); bit <<= 1)
        if ((node ^ bit) < nodes_) out.push_back(node ^ bit);
      break;
    case TopologyKind::kTorus2D: {
      const std::uint32_t r = node / cols_, c = node % cols_;
      out = {((r + 1) % rows_) * cols_ + c, ((r + rows_ - 1) % rows_) * cols_ + c, r * cols_ + (c + 1) % cols_,
             r * cols_ + (c + cols_ - 1) % cols_};
      break;
    }
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  out.erase(std::remove(out.begin(), out.end(), node), out.end());
  return out;
}

std::uint32_t Topology::diameter() const {
  switch (kind_) {
    case TopologyKind::kRing: return nodes_ / 2;
    case TopologyKind::kHypercube: return nodes_ <= 1 ? 0 : std::uint32_t(std::bit_width(nodes_ - 1));
    case TopologyKind::kTorus2D: return rows_ / 2 + cols_ / 2;
  }
  return 0;
}

}  // namespace raynode::nodes
