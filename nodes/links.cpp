#include "nodes/links.h"

#include <algorithm>
#include <bit>
#include <stdexcept>

namespace raynode::nodes {

LinkNetwork::LinkNetwork(const Topology& topology) : topology_(topology) {
  const std::uint32_t n = topology.nodes();
  std::uint32_t ids = n;  // link ids: from-node x ports
  switch (topology.kind()) {
    case TopologyKind::kRing: ports_ = 2; break;  // 0 forward, 1 backward
    case TopologyKind::kHypercube:
      // An incomplete hypercube's e-cube route may pass through addresses
      // >= N: their routers are there, as in a partly filled cabinet.
      ports_ = std::max<std::uint32_t>(1, std::uint32_t(std::bit_width(std::bit_ceil(n) - 1)));
      ids = std::bit_ceil(n);
      break;
    case TopologyKind::kTorus2D: ports_ = 4; break;  // +col, -col, +row, -row
  }
  timelines_.resize(std::size_t(ids) * ports_);
  locks_ = std::make_unique<SpinLock[]>(timelines_.size());
}

class LinkNetwork::RouteLock {
 public:
  /// `sorted` is the caller's buffer, filled here (a thread's own, reused).
  RouteLock(LinkNetwork& net, const std::vector<std::uint32_t>& route, std::vector<std::uint32_t>& sorted)
      : net_(net), sorted_(sorted) {
    sorted_.assign(route.begin(), route.end());
    std::sort(sorted_.begin(), sorted_.end());
    for (std::uint32_t l : sorted_) net_.locks_[l].lock();
  }
  ~RouteLock() {
    for (std::uint32_t l : sorted_) net_.locks_[l].unlock();
  }
  RouteLock(const RouteLock&) = delete;
  RouteLock& operator=(const RouteLock&) = delete;

 private:
  LinkNetwork& net_;
  std::vector<std::uint32_t>& sorted_;
};

namespace {

/// The calling thread's route buffers (no allocation per message).
std::vector<std::uint32_t>& route_buffer() {
  thread_local std::vector<std::uint32_t> links;
  return links;
}
std::vector<std::uint32_t>& sorted_buffer() {
  thread_local std::vector<std::uint32_t> links;
  return links;
}

}  // namespace

void LinkNetwork::route(NodeId a, NodeId b, std::vector<std::uint32_t>& links) const {
  links.clear();
  if (a == b) return;
  const std::uint32_t n = topology_.nodes();
  switch (topology_.kind()) {
    case TopologyKind::kRing: {
      const std::uint32_t forward = (b + n - a) % n;
      const bool fwd = forward <= n - forward;
      for (NodeId at = a; at != b; at = fwd ? (at + 1) % n : (at + n - 1) % n) links.push_back(link_id(at, fwd ? 0 : 1));
      break;
    }
    case TopologyKind::kHypercube:
      for (NodeId at = a; at != b;) {
        const std::uint32_t dim = std::uint32_t(std::countr_zero(at ^ b));
        links.push_back(link_id(at, dim));
        at ^= 1u << dim;
      }
      break;
    case TopologyKind::kTorus2D: {
      const std::uint32_t cols = topology_.cols(), rows = topology_.rows();
      std::uint32_t r = a / cols, c = a % cols;
      const std::uint32_t rb = b / cols, cb = b % cols;
      const std::uint32_t fc = (cb + cols - c) % cols, fr = (rb + rows - r) % rows;
      const bool plus_c = fc <= cols - fc, plus_r = fr <= rows - fr;
      while (c != cb) {
        links.push_back(link_id(r * cols + c, plus_c ? 0 : 1));
        c = plus_c ? (c + 1) % cols : (c + cols - 1) % cols;
      }
      while (r != rb) {
        links.push_back(link_id(r * cols + c, plus_r ? 2 : 3));
        r = plus_r ? (r + 1) % rows : (r + rows - 1) % rows;
      }
      break;
    }
  }
}

double LinkNetwork::reserve(NodeId a, NodeId b, double ready, double hold) {
  std::vector<std::uint32_t>& links = route_buffer();
  route(a, b, links);
  const RouteLock lock(*this, links, sorted_buffer());
  double start = ready;
  // Move the start past each conflict until one time suits every link.
  for (bool moved = true; moved;) {
    moved = false;
    for (std::uint32_t l : links) {
      const double s = timelines_[l].first_gap(start, hold);
      if (s > start) {
        start = s;
        moved = true;
      }
    }
  }
  for (std::uint32_t l : links) timelines_[l].book(start, hold);
  return start;
}

void LinkNetwork::cancel(NodeId a, NodeId b, double start, double hold) {
  std::vector<std::uint32_t>& links = route_buffer();
  route(a, b, links);
  const RouteLock lock(*this, links, sorted_buffer());
  for (std::uint32_t l : links) timelines_[l].cancel(start, hold);
}

}  // namespace raynode::nodes
