#include "nodes/scheduler.h"

#include <fmt/core.h>

#include <limits>

namespace raynode::nodes {

Scheduler::Scheduler(std::uint32_t nodes, std::uint32_t permits, double window,
                     std::function<void(std::uint32_t)> wake)
    : enabled_(permits > 0 && window >= 0 && nodes > 1),
      window_(window),
      wake_(std::move(wake)),
      free_permits_(permits),
      state_(nodes, kActiveWaiting),
      clock_(nodes, 0.0),
      resuming_(nodes, 0),
      granted_(new std::atomic<bool>[nodes]) {
  for (std::uint32_t i = 0; i < nodes; ++i) granted_[i].store(false, std::memory_order_relaxed);
}

double Scheduler::min_active_clock() const {
  double m = std::numeric_limits<double>::infinity();
  for (std::size_t j = 0; j < state_.size(); ++j)
    if (state_[j] != kInactive && clock_[j] < m) m = clock_[j];
  return m;
}

void Scheduler::grant_eligible(std::vector<std::uint32_t>& wake) {
  const double limit = min_active_clock() + window_;
  while (free_permits_ > 0) {
    // A node resuming inside its work unit first, whatever its clock; else
    // the lowest queued node, if it may run.
    std::int64_t best = -1;
    for (std::size_t j = 0; j < state_.size(); ++j) {
      if (state_[j] != kActiveWaiting) continue;
      if (best < 0 || (resuming_[j] && !resuming_[std::size_t(best)]) ||
          (resuming_[j] == resuming_[std::size_t(best)] && clock_[j] < clock_[std::size_t(best)]))
        best = std::int64_t(j);
    }
    if (best < 0 || (!resuming_[std::size_t(best)] && clock_[std::size_t(best)] > limit)) return;
    resuming_[std::size_t(best)] = false;
    --free_permits_;
    state_[std::size_t(best)] = kRunning;
    // release: the grantee's acquire load in its wait sees the permit.
    granted_[std::size_t(best)].store(true, std::memory_order_release);
    wake.push_back(std::uint32_t(best));
  }
}

void Scheduler::take_permit_back(std::uint32_t node) {
  if (state_[node] == kRunning) {
    granted_[node].store(false, std::memory_order_relaxed);
    ++free_permits_;
  }
}

bool Scheduler::try_run(std::uint32_t node, double clock, bool resume) {
  if (!enabled_) return true;
  if (granted_[node].load(std::memory_order_acquire)) return true;
  std::vector<std::uint32_t> wake;
  bool ok;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    // Granted between the lock-free check and here: do not overwrite it.
    if (state_[node] == kRunning) return true;
    state_[node] = kActiveWaiting;
    if (resume) resuming_[node] = true;
    clock_[node] = clock;
    grant_eligible(wake);
    ok = state_[node] == kRunning;
  }
  for (std::uint32_t j : wake)
    if (j != node) wake_(j);
  return ok;
}

bool Scheduler::yield_point(std::uint32_t node, double clock) {
  if (!enabled_) return true;
  std::vector<std::uint32_t> wake;
  bool ok;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (state_[node] != kRunning) return false;
    clock_[node] = clock;
    if (clock > min_active_clock() + window_) {
      // Too far ahead of someone active: give the permit back and queue.
      take_permit_back(node);
      state_[node] = kActiveWaiting;
      ++handoffs_;
    }
    grant_eligible(wake);  // our progress may have raised the minimum
    ok = state_[node] == kRunning;
  }
  for (std::uint32_t j : wake)
    if (j != node) wake_(j);
  return ok;
}

std::string Scheduler::describe() {
  if (!enabled_) return "scheduler off";
  std::lock_guard<std::mutex> lock(mutex_);
  std::string running, queued, awaiting;
  std::size_t n_running = 0, n_queued = 0, n_awaiting = 0;
  for (std::size_t j = 0; j < state_.size(); ++j) {
    if (state_[j] == kRunning && n_running++ < 8) running += fmt::format(" {}@{:.6g}", j, clock_[j]);
    if (state_[j] == kActiveWaiting && n_queued++ < 8) queued += fmt::format(" {}@{:.6g}", j, clock_[j]);
    if (state_[j] == kAwaiting && n_awaiting++ < 8) awaiting += fmt::format(" {}@{:.6g}", j, clock_[j]);
  }
  return fmt::format("scheduler: {} free permits, {} running [{} ], {} queued [{} ], {} awaiting a reply [{} ], "
                     "window {:.3g} s",
                     free_permits_, n_running, running, n_queued, queued, n_awaiting, awaiting, window_);
}

void Scheduler::await_reply(std::uint32_t node, double clock) {
  if (!enabled_) return;
  std::vector<std::uint32_t> wake;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    take_permit_back(node);
    state_[node] = kAwaiting;
    clock_[node] = clock;
    grant_eligible(wake);
  }
  for (std::uint32_t j : wake) wake_(j);
}

void Scheduler::release(std::uint32_t node) {
  if (!enabled_) return;
  std::vector<std::uint32_t> wake;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (state_[node] == kInactive) return;
    take_permit_back(node);
    state_[node] = kInactive;
    grant_eligible(wake);
  }
  for (std::uint32_t j : wake) wake_(j);
}

}  // namespace raynode::nodes
