// A node's mailbox: a bounded, lock-free, multi-producer single-consumer
// queue of fixed-size slots, each holding one message header and up to
// `max_payload` payload bytes (docs/architecture.md, "Mailbox").
//
// Place in the data flow: any thread's NodeContext::send -> try_push into the
// receiver's mailbox; the owner's NodeContext::receive -> try_pop / wait.
//
// Algorithm: Dmitry Vyukov's bounded MPMC queue ("Bounded MPMC queue",
// 1024cores.net, 2010), used with a single consumer, so the dequeue index is
// a plain variable of the owner thread. Every slot carries a sequence number:
// seq == pos means "free for the producer that claims position pos",
// seq == pos + 1 means "filled, ready for the consumer at pos"; the consumer
// frees it for the next lap with seq = pos + capacity. Producers claim
// positions with a CAS on the enqueue index. `try_push` never waits: a full
// mailbox returns false (the dataflow mode's deadlock case needs the sender
// to see it). The slot array lives in the owner's Arena.
//
// Waiting: the consumer blocks in a futex wait (Linux) on a wake-up counter
// rather than spinning, so hundreds of idle node threads cost
// nothing on a 2-core machine. A producer bumps the counter and notifies only
// when the consumer has announced that it is going to sleep; a pair of
// seq_cst fences (Dekker's pattern) guarantees that either the producer sees
// the announcement or the consumer sees the new message, so no wake-up is lost.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <new>
#include <span>

#include "nodes/arena.h"
#include "nodes/message.h"

namespace raynode::nodes {

class Mailbox {
 public:
  /// `capacity` slots (rounded up to a power of two, >= 2) of `max_payload`
  /// bytes each, allocated from `arena` (throws ArenaExhausted).
  Mailbox(Arena& arena, std::uint32_t capacity, std::uint32_t max_payload);
  Mailbox(const Mailbox&) = delete;
  Mailbox& operator=(const Mailbox&) = delete;
  ~Mailbox();

  std::uint32_t capacity() const { return capacity_; }
  std::uint32_t max_payload() const { return max_payload_; }
  /// Bytes of arena memory the slots take.
  std::size_t bytes() const { return std::size_t(capacity_) * stride_; }
  /// Bytes per slot for a given payload limit (for sizing before creating).
  static std::size_t slot_bytes(std::uint32_t max_payload);
  /// Arena bytes a mailbox of `capacity` slots of `max_payload` bytes takes.
  static std::size_t bytes_for(std::uint32_t capacity, std::uint32_t max_payload);

  /// Copies the header and the concatenation of `parts` into a free slot and
  /// publishes it. Any thread; lock-free. Returns false, changing nothing,
  /// if the mailbox is full. Throws std::length_error if the parts exceed
  /// max_payload. header.payload_bytes is set from the parts.
  /// `crowded`, when given, is set to whether the mailbox held at least
  /// half its capacity after this push (the message pushed capacity/2
  /// positions earlier is still unread): one extra load. `woke`, when
  /// given, is set to whether the push woke the sleeping owner (a futex
  /// system call).
  bool try_push(MessageHeader header, std::span<const std::span<const std::byte>> parts, bool* crowded = nullptr,
                bool* woke = nullptr);

  /// Owner thread only: pops the oldest published message, copying its
  /// payload into `payload_out` (at least max_payload bytes). Returns false
  /// if empty. Wait-free.
  bool try_pop(MessageHeader& header, std::byte* payload_out);

  /// Owner thread only: blocks until a message may be available, `stop` is
  /// true (checked after announcing the sleep), or `timeout_s` seconds
  /// passed (0 = no timeout). Spurious returns are allowed; callers loop.
  /// `also`, when given, is one more flag that ends the wait (a run permit).
  void wait(const std::atomic<bool>& stop, double timeout_s = 0, const std::atomic<bool>* also = nullptr);
  /// Owner thread only: like wait(), but without announcing the sleep, so
  /// producers never make the wake-up system call for it: it returns after
  /// `timeout_s` seconds (> 0), on wake(), or at once if a message or `stop`
  /// is there. For a consumer that need not react at once to each message
  /// (the host): a busy producer then runs on instead of handing its core
  /// to the consumer per message.
  void wait_quietly(const std::atomic<bool>& stop, double timeout_s);
  /// Owner thread only: blocks until `a` or `b` is set, `stop` is true, or
  /// `timeout_s` seconds passed (0 = no timeout), whatever mail comes: the
  /// setter must call wake() after setting its flag. Without announcing the
  /// sleep, so producers never wake the owner (the virtual-time scheduler's
  /// service permits do, scheduler.h). Spurious returns are allowed.
  void wait_for_flags(const std::atomic<bool>& stop, double timeout_s, const std::atomic<bool>& a,
                      const std::atomic<bool>& b);
  /// Any thread: wakes the owner if it waits. To stop a run, set the stop
  /// flag (release or stronger) first, then call wake().
  void wake();

  /// Owner thread only: is a published message waiting? Lock-free, no
  /// system call (one acquire load): the cheap check before a poll.
  bool has_message() const { return nonempty_for_consumer(); }

  /// Any thread: is the next slot still taken (a push now would find the
  /// mailbox full)? One relaxed and one acquire load; a hint, as the owner
  /// may pop at once.
  bool looks_full() const {
    const std::uint64_t pos = enqueue_pos_.load(std::memory_order_relaxed);
    return std::int64_t(slot(pos)->seq.load(std::memory_order_acquire)) - std::int64_t(pos) < 0;
  }
  /// Approximate number of queued messages (any thread; for statistics).
  std::uint32_t approximate_size() const;
  /// Owner thread only: positions producers have claimed and the owner has
  /// not popped (messages published or still being written), at most
  /// capacity(): one relaxed load, no scan.
  std::uint32_t claimed() const {
    return std::uint32_t(enqueue_pos_.load(std::memory_order_relaxed) - dequeue_pos_);
  }

 private:
  struct alignas(64) SlotHead {
    std::atomic<std::uint64_t> seq;
    MessageHeader header;
  };
  SlotHead* slot(std::uint64_t pos) const {
    return std::launder(reinterpret_cast<SlotHead*>(slots_ + (pos & mask_) * stride_));
  }
  bool nonempty_for_consumer() const;

  Arena* arena_;
  std::uint32_t capacity_;
  std::uint32_t max_payload_;
  std::uint64_t mask_;
  std::size_t stride_;
  std::byte* slots_ = nullptr;
  alignas(64) std::atomic<std::uint64_t> enqueue_pos_{0};  // shared by producers
  alignas(64) std::uint64_t dequeue_pos_ = 0;              // owner only
  alignas(64) std::atomic<std::uint32_t> wake_count_{0};   // futex word
  std::atomic<bool> sleeping_{false};
};

}  // namespace raynode::nodes
