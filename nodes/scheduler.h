// Virtual-time scheduling of the node threads: at most K of them compute at
// once (K = the host's hardware threads), and the ones with the smallest
// virtual clocks get to. Without it, which emulated node runs is up to the
// operating system, so a node that happens to get the CPU early races ahead
// in virtual time and decisions driven by message order (who steals work
// from whom) follow the host's thread scheduling instead of the emulated
// machine's time; with 64 nodes on 2 cores the measured efficiency fell to
// ~35% for a perfectly balanced image. With it, the emulation behaves like a
// discrete-event simulation that always advances the laggards, and only K
// threads are runnable, so many nodes cost no more wall time than K.
//
// Protocol (node side, see work.h's farm loop): before computing, a node
// asks for a run permit (try_run); if none is free it is queued with its
// clock and waits for mail or for the permit (granted by waking its
// mailbox). Between work units it calls yield_point: if a queued node's
// clock is more than `window` behind its own, the permit passes to the
// laggard and the caller queues. A node that blocks for mail or ends its
// work releases its permit (release).
//
// Thread safety: all members are called by node threads; one mutex guards
// the queue (a few hundred nanoseconds per work unit).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <vector>

namespace raynode::nodes {

class Scheduler {
 public:
  /// `wake(node)` wakes a node's mailbox wait. permits >= 1; window >= 0
  /// virtual seconds; permits = 0 or window < 0 disables scheduling (every
  /// call grants).
  Scheduler(std::uint32_t nodes, std::uint32_t permits, double window, std::function<void(std::uint32_t)> wake);

  bool enabled() const { return enabled_; }
  /// Does `node` hold a permit? If not, takes a free one, or queues the node
  /// with `clock` and returns false.
  bool try_run(std::uint32_t node, double clock);
  /// Between work units: returns true to go on, or false after handing the
  /// permit to a queued node more than `window` behind `clock` (the caller
  /// is then queued).
  bool yield_point(std::uint32_t node, double clock);
  /// Gives up the permit and leaves the queue (blocking for mail, or done).
  void release(std::uint32_t node);
  /// The flag a waiting node's mailbox wait also watches: set when a permit
  /// is granted to it.
  const std::atomic<bool>& granted_flag(std::uint32_t node) const { return granted_[node]; }

  std::uint64_t handoffs() const { return handoffs_; }

 private:
  /// Index of the queued node with the smallest clock, or -1. Lock held.
  std::int64_t lowest_waiting() const;
  /// Gives the permit to queued node j. Lock held; returns j for waking.
  void grant(std::uint32_t j);

  bool enabled_;
  double window_;
  std::function<void(std::uint32_t)> wake_;
  std::mutex mutex_;
  std::uint32_t free_permits_;
  std::vector<char> waiting_;
  std::vector<double> wait_clock_;
  std::unique_ptr<std::atomic<bool>[]> granted_;  ///< holds a permit (read lock-free by its owner)
  std::uint64_t handoffs_ = 0;
};

}  // namespace raynode::nodes
