#include <algorithm>
#include "nodes/mailbox.h"

#include <fmt/core.h>

#include <linux/futex.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <bit>
#include <climits>
#include <ctime>
#include <cstring>
#include <stdexcept>

namespace raynode::nodes {

namespace {

// The futex word is the std::atomic<uint32_t>'s own storage (same size and
// representation, as libstdc++'s own atomic wait assumes). We call futex
// directly rather than std::atomic::wait/notify because we need a timed
// wait, and libstdc++'s notify skips the system call unless a waiter was
// registered through its own wait.
std::uint32_t* futex_word(std::atomic<std::uint32_t>& a) { return reinterpret_cast<std::uint32_t*>(&a); }

void futex_wait(std::atomic<std::uint32_t>& word, std::uint32_t expected, double timeout_s) {
  timespec ts{};
  timespec* tp = nullptr;
  if (timeout_s > 0) {
    ts.tv_sec = time_t(timeout_s);
    ts.tv_nsec = long((timeout_s - double(ts.tv_sec)) * 1e9);
    tp = &ts;
  }
  // Returns at once if the word no longer holds `expected` (EAGAIN), on a
  // wake, a signal or the timeout: callers re-check their condition.
  syscall(SYS_futex, futex_word(word), FUTEX_WAIT_PRIVATE, expected, tp, nullptr, 0);
}

void futex_wake(std::atomic<std::uint32_t>& word, int count) {
  syscall(SYS_futex, futex_word(word), FUTEX_WAKE_PRIVATE, count, nullptr, nullptr, 0);
}

}  // namespace

std::size_t Mailbox::slot_bytes(std::uint32_t max_payload) {
  const std::size_t raw = sizeof(SlotHead) + std::size_t(max_payload);
  return (raw + 63) / 64 * 64;
}

namespace {
std::uint32_t rounded_capacity(std::uint32_t capacity) { return std::bit_ceil(std::max<std::uint32_t>(capacity, 2)); }
}  // namespace

std::size_t Mailbox::bytes_for(std::uint32_t capacity, std::uint32_t max_payload) {
  return std::size_t(rounded_capacity(capacity)) * slot_bytes(max_payload);
}

Mailbox::Mailbox(Arena& arena, std::uint32_t capacity, std::uint32_t max_payload)
    : arena_(&arena),
      capacity_(rounded_capacity(capacity)),
      max_payload_(max_payload),
      mask_(capacity_ - 1),
      stride_(slot_bytes(max_payload)) {
  slots_ = static_cast<std::byte*>(arena.allocate_bytes(bytes(), 64, "its mailbox"));
  for (std::uint64_t i = 0; i < capacity_; ++i) {
    SlotHead* s = new (slots_ + i * stride_) SlotHead{};
    s->seq.store(i, std::memory_order_relaxed);
  }
}

Mailbox::~Mailbox() {
  for (std::uint64_t i = 0; i < capacity_; ++i) slot(i)->~SlotHead();
  arena_->deallocate_bytes(slots_, bytes(), 64);
}

bool Mailbox::try_push(MessageHeader header, std::span<const std::span<const std::byte>> parts, bool* crowded,
                       bool* woke) {
  std::size_t total = 0;
  for (const auto& p : parts) total += p.size();
  if (total > max_payload_)
    throw std::length_error(fmt::format("{} message of {} B exceeds the mailbox slot of {} B",
                                        message_type_name(header.type), total, max_payload_));
  header.payload_bytes = std::uint32_t(total);

  // Claim a position. relaxed loads/CAS of the index suffice: the slot's
  // sequence number, not the index, orders the slot's contents.
  std::uint64_t pos = enqueue_pos_.load(std::memory_order_relaxed);
  SlotHead* s;
  for (;;) {
    s = slot(pos);
    // acquire: pairs with the consumer's release store that freed the slot,
    // so its reads of the previous message happen before our writes.
    const std::uint64_t seq = s->seq.load(std::memory_order_acquire);
    const std::int64_t dif = std::int64_t(seq) - std::int64_t(pos);
    if (dif == 0) {
      if (enqueue_pos_.compare_exchange_weak(pos, pos + 1, std::memory_order_relaxed)) break;
    } else if (dif < 0) {
      return false;  // the slot still holds the message of the previous lap: full
    } else {
      pos = enqueue_pos_.load(std::memory_order_relaxed);  // another producer took pos
    }
  }
  s->header = header;
  std::byte* dst = reinterpret_cast<std::byte*>(s) + sizeof(SlotHead);
  for (const auto& p : parts) {
    if (!p.empty()) std::memcpy(dst, p.data(), p.size());
    dst += p.size();
  }
  // release: publishes the header and payload to the consumer's acquire load.
  s->seq.store(pos + 1, std::memory_order_release);

  if (crowded) {
    // Position q = pos - capacity/2 still published and unread means at
    // least capacity/2 + 1 messages wait (a stale read only errs late).
    const std::uint64_t half = std::max<std::uint64_t>(1, capacity_ / 2);
    const std::uint64_t q = pos - half;
    *crowded = pos >= half && slot(q)->seq.load(std::memory_order_relaxed) == q + 1;
  }

  // Dekker with wait(): our fence orders the publication before reading
  // `sleeping_`; the consumer's fence orders its announcement before
  // re-checking the queue. At least one side sees the other.
  std::atomic_thread_fence(std::memory_order_seq_cst);
  const bool wake = sleeping_.load(std::memory_order_relaxed);
  if (wake) {
    // release: a consumer whose acquire load of the counter sees this bump
    // also sees the publication above.
    wake_count_.fetch_add(1, std::memory_order_release);
    futex_wake(wake_count_, 1);
  }
  if (woke) *woke = wake;
  return true;
}

bool Mailbox::try_pop(MessageHeader& header, std::byte* payload_out) {
  const std::uint64_t pos = dequeue_pos_;
  SlotHead* s = slot(pos);
  // acquire: pairs with the producer's release store of seq = pos + 1.
  if (s->seq.load(std::memory_order_acquire) != pos + 1) return false;  // empty, or a producer mid-copy
  header = s->header;
  if (header.payload_bytes)
    std::memcpy(payload_out, reinterpret_cast<const std::byte*>(s) + sizeof(SlotHead), header.payload_bytes);
  // release: our reads above happen before the next producer's writes.
  s->seq.store(pos + capacity_, std::memory_order_release);
  dequeue_pos_ = pos + 1;
  return true;
}

bool Mailbox::nonempty_for_consumer() const {
  return slot(dequeue_pos_)->seq.load(std::memory_order_acquire) == dequeue_pos_ + 1;
}

void Mailbox::wait(const std::atomic<bool>& stop, double timeout_s, const std::atomic<bool>* also) {
  // Read the counter first: any bump after this read makes the futex wait
  // return at once (its value no longer matches).
  const std::uint32_t w = wake_count_.load(std::memory_order_acquire);
  sleeping_.store(true, std::memory_order_relaxed);
  std::atomic_thread_fence(std::memory_order_seq_cst);
  // `stop` is set before wake() bumps the counter: if our read of w saw that
  // bump we see `stop` here, otherwise the bump wakes the futex wait.
  if (!nonempty_for_consumer() && !stop.load(std::memory_order_acquire) &&
      !(also && also->load(std::memory_order_acquire)))
    futex_wait(wake_count_, w, timeout_s);
  sleeping_.store(false, std::memory_order_relaxed);
}

void Mailbox::wait_quietly(const std::atomic<bool>& stop, double timeout_s) {
  // As in wait(): a wake() after this read changes the counter, so the
  // futex wait returns at once; `sleeping_` stays false, so try_push never
  // bumps it.
  const std::uint32_t w = wake_count_.load(std::memory_order_acquire);
  if (!nonempty_for_consumer() && !stop.load(std::memory_order_acquire)) futex_wait(wake_count_, w, timeout_s);
}

void Mailbox::wait_for_flags(const std::atomic<bool>& stop, double timeout_s, const std::atomic<bool>& a,
                             const std::atomic<bool>& b) {
  // As in wait(): a flag set before wake() bumps the counter is seen here
  // if our read of w saw the bump; otherwise the bump ends the futex wait.
  const std::uint32_t w = wake_count_.load(std::memory_order_acquire);
  if (!stop.load(std::memory_order_acquire) && !a.load(std::memory_order_acquire) &&
      !b.load(std::memory_order_acquire))
    futex_wait(wake_count_, w, timeout_s);
}

void Mailbox::wake() {
  wake_count_.fetch_add(1, std::memory_order_release);
  futex_wake(wake_count_, INT_MAX);
}

std::uint32_t Mailbox::approximate_size() const {
  // Counts the slots whose sequence number says "published, not popped".
  std::uint64_t filled = 0;
  for (std::uint64_t i = 0; i < capacity_; ++i) {
    const std::uint64_t seq = slot(i)->seq.load(std::memory_order_relaxed);
    if ((seq & mask_) == ((i + 1) & mask_)) ++filled;  // seq = pos + 1: published, not yet popped
  }
  return std::uint32_t(filled);
}

}  // namespace raynode::nodes
