// A dataflow node's sending queue (the paper's "Deadlock" section): ray
// messages that found their destination's mailbox full wait here, in the
// node's own memory, until the destination has room; only when this queue
// is full does a ray go to the host (node_tracer.cpp, route).
//
// Layout: one pool of slots in the node's arena, chained into a FIFO list
// per destination, plus the list of destinations that have rays waiting,
// so that a pass over the queue costs O(destinations waiting + rays sent),
// not O(rays waiting). Slots are handed out fresh before any is reused, so
// a large pool that is never filled is never touched.
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>

#include "dataflow/messages.h"
#include "nodes/arena.h"

namespace raynode::dataflow {

class SendQueue {
 public:
  /// Arena bytes per slot.
  static constexpr std::size_t kSlotBytes = sizeof(RayMsg) + sizeof(std::uint32_t);
  /// Arena bytes for `nodes` destinations, besides the slots.
  static constexpr std::size_t destination_bytes(std::uint32_t nodes) { return std::size_t(nodes) * 3 * sizeof(std::uint32_t); }

  SendQueue() = default;
  /// `slots` rays (>= 1) for destinations 0 .. nodes-1, from arena `a`.
  /// Throws nodes::ArenaExhausted.
  SendQueue(nodes::Arena& a, std::size_t slots, std::uint32_t nodes)
      : slots_(a, slots, "its sending queue", nodes::kUninitialized),
        next_(a, slots, "its sending queue's links", nodes::kUninitialized),
        head_(a, nodes, "its sending queue's heads", nodes::kUninitialized),
        tail_(a, nodes, "its sending queue's tails", nodes::kUninitialized),
        waiting_(a, nodes, "its sending queue's destinations", nodes::kUninitialized) {
    if (slots == 0 || slots >= kNone) throw std::invalid_argument("a sending queue needs 1 to 2^32-2 slots");
    for (std::uint32_t d = 0; d < nodes; ++d) head_[d] = kNone;
  }

  std::size_t size() const { return size_; }
  std::size_t capacity() const { return slots_.size(); }
  bool empty() const { return size_ == 0; }

  /// Queues `m` behind the rays for the same destination (m.region, which
  /// must be < nodes). False, and nothing queued, when the queue is full.
  bool push(const RayMsg& m) {
    std::uint32_t i;
    if (free_ != kNone) {
      i = free_;
      free_ = next_[i];
    } else if (fresh_ < slots_.size()) {
      i = std::uint32_t(fresh_++);
    } else {
      return false;
    }
    slots_[i] = m;
    next_[i] = kNone;
    const std::uint32_t d = m.region;
    if (head_[d] == kNone) {
      head_[d] = i;
      waiting_[n_waiting_++] = d;
    } else {
      next_[tail_[d]] = i;
    }
    tail_[d] = i;
    ++size_;
    return true;
  }

  /// One pass: for each destination with rays waiting, hands them to
  /// `try_send(const RayMsg&) -> bool` oldest first until it refuses one
  /// (the destination is still full; that ray stays first). Returns the
  /// number of rays sent.
  template <class TrySend>
  std::size_t drain(TrySend&& try_send) {
    std::size_t sent = 0;
    for (std::uint32_t k = 0; k < n_waiting_;) {
      const std::uint32_t d = waiting_[k];
      while (head_[d] != kNone && try_send(static_cast<const RayMsg&>(slots_[head_[d]]))) {
        const std::uint32_t i = head_[d];
        head_[d] = next_[i];
        next_[i] = free_;
        free_ = i;
        --size_;
        ++sent;
      }
      if (head_[d] != kNone) {
        ++k;
        continue;
      }
      waiting_[k] = waiting_[--n_waiting_];  // d has none left: the last destination takes its place
    }
    return sent;
  }

 private:
  static constexpr std::uint32_t kNone = 0xffffffffu;
  nodes::ArenaArray<RayMsg> slots_;
  nodes::ArenaArray<std::uint32_t> next_;        ///< per slot: the next slot of its list (or of the free list)
  nodes::ArenaArray<std::uint32_t> head_, tail_;  ///< per destination: its oldest and newest slot (head kNone: none)
  nodes::ArenaArray<std::uint32_t> waiting_;     ///< destinations with rays waiting, [0, n_waiting_)
  std::uint32_t n_waiting_ = 0;
  std::uint32_t free_ = kNone;  ///< slots given back
  std::size_t fresh_ = 0;       ///< slots [fresh_, capacity) never used yet
  std::size_t size_ = 0;
};

}  // namespace raynode::dataflow
