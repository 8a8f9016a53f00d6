// The network's links in virtual time, for link contention (NetworkModel::
// contention; docs/architecture.md, "Virtual time").
//
// The iPSC/2's Direct-Connect routers set up a circuit from the sender to the
// receiver and stream the message through it (S. F. Nugent, "The iPSC/2
// Direct-Connect communications technology", 3rd Conf. on Hypercube
// Concurrent Computers and Applications, 1988): wormhole-like, a message
// holds every link of its route until its tail has passed, and a message
// that needs a held link waits for it. Links are full duplex, so the two
// directions are separate resources.
//
// Routes are deterministic and minimal: e-cube on the hypercube (the
// differing address bits corrected from the lowest up, as the iPSC/2
// routes), the shorter way round the ring (forward on a tie), and on the
// torus the columns first, then the rows, each the shorter way. Messages
// to or from the host (attached to node 0) do not contend: the host's own
// connection is not a hypercube link.
//
// Thread safety: a reservation locks the links of its route (per-link locks,
// taken in ascending order).
#pragma once

#include <cstdint>
#include <atomic>
#include <memory>
#include <thread>
#include <vector>

#include "nodes/arena.h"
#include "nodes/timeline.h"
#include "nodes/topology.h"

namespace raynode::nodes {

class LinkNetwork {
 public:
  explicit LinkNetwork(const Topology& topology);

  /// Directed links from `a` to `b` (nodes, a != b), in route order; the
  /// route has topology.hops(a, b) links.
  void route(NodeId a, NodeId b, std::vector<std::uint32_t>& links) const;

  /// Reserves the route from `a` to `b` for `hold` virtual seconds from the
  /// first time at or after `ready` when every one of its links is free so
  /// long; returns that time (the message's head enters the network then).
  double reserve(NodeId a, NodeId b, double ready, double hold);
  /// Gives back a reservation made at `start` (a send that found the
  /// destination mailbox full and will be made again).
  void cancel(NodeId a, NodeId b, double start, double hold);

  /// Directed links in all (for tests).
  std::size_t links() const { return timelines_.size(); }

 private:
  std::uint32_t link_id(NodeId from, std::uint32_t port) const { return from * ports_ + port; }

  const Topology& topology_;
  std::uint32_t ports_ = 1;  ///< directed links leaving each node
  std::vector<BusyTimeline> timelines_;
  /// A short spin lock per link: held for a few map operations, and only
  /// the few node threads that hold run permits send at once (scheduler.h),
  /// so a waiter spins briefly and yields rather than sleeping in the kernel.
  class SpinLock {
   public:
    void lock() {
      for (int spins = 0; flag_.test_and_set(std::memory_order_acquire); ++spins)
        if (spins >= 64) std::this_thread::yield();
    }
    void unlock() { flag_.clear(std::memory_order_release); }

   private:
    std::atomic_flag flag_ = ATOMIC_FLAG_INIT;
  };
  /// Locks the links of `route` (ascending ids, so two reservations never
  /// wait for each other in a cycle), unlocks them on destruction.
  class RouteLock;
  std::unique_ptr<SpinLock[]> locks_;  ///< one per link
};

}  // namespace raynode::nodes
