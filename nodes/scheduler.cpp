#include "nodes/scheduler.h"

namespace raynode::nodes {

Scheduler::Scheduler(std::uint32_t nodes, std::uint32_t permits, double window,
                     std::function<void(std::uint32_t)> wake)
    : enabled_(permits > 0 && window >= 0 && permits < nodes),
      window_(window),
      wake_(std::move(wake)),
      free_permits_(permits),
      waiting_(nodes, 0),
      wait_clock_(nodes, 0.0),
      granted_(new std::atomic<bool>[nodes]) {
  for (std::uint32_t i = 0; i < nodes; ++i) granted_[i].store(false, std::memory_order_relaxed);
}

std::int64_t Scheduler::lowest_waiting() const {
  std::int64_t best = -1;
  for (std::size_t j = 0; j < waiting_.size(); ++j)
    if (waiting_[j] && (best < 0 || wait_clock_[j] < wait_clock_[std::size_t(best)])) best = std::int64_t(j);
  return best;
}

void Scheduler::grant(std::uint32_t j) {
  waiting_[j] = 0;
  // release: the grantee's acquire load in its wait sees the permit.
  granted_[j].store(true, std::memory_order_release);
}

bool Scheduler::try_run(std::uint32_t node, double clock) {
  if (!enabled_) return true;
  if (granted_[node].load(std::memory_order_acquire)) return true;
  std::lock_guard<std::mutex> lock(mutex_);
  if (granted_[node].load(std::memory_order_relaxed)) return true;
  if (free_permits_ > 0) {
    --free_permits_;
    waiting_[node] = 0;
    granted_[node].store(true, std::memory_order_relaxed);
    return true;
  }
  waiting_[node] = 1;
  wait_clock_[node] = clock;
  return false;
}

bool Scheduler::yield_point(std::uint32_t node, double clock) {
  if (!enabled_) return true;
  std::int64_t j;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!granted_[node].load(std::memory_order_relaxed)) return false;
    j = lowest_waiting();
    if (j < 0 || !(wait_clock_[std::size_t(j)] + window_ < clock)) return true;
    granted_[node].store(false, std::memory_order_relaxed);
    waiting_[node] = 1;
    wait_clock_[node] = clock;
    grant(std::uint32_t(j));
    ++handoffs_;
  }
  wake_(std::uint32_t(j));
  return false;
}

void Scheduler::release(std::uint32_t node) {
  if (!enabled_) return;
  std::int64_t j = -1;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    waiting_[node] = 0;
    if (!granted_[node].load(std::memory_order_relaxed)) return;
    granted_[node].store(false, std::memory_order_relaxed);
    j = lowest_waiting();
    if (j < 0) {
      ++free_permits_;
      return;
    }
    grant(std::uint32_t(j));
  }
  wake_(std::uint32_t(j));
}

}  // namespace raynode::nodes
