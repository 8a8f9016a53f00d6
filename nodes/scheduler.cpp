#include "nodes/scheduler.h"

#include <fmt/core.h>

#include <algorithm>
#include <limits>

namespace raynode::nodes {

Scheduler::Scheduler(std::uint32_t nodes, std::uint32_t permits, double window,
                     std::function<void(std::uint32_t)> wake, bool scheduled_mail)
    : enabled_(permits > 0 && window >= 0 && nodes > 1),
      scheduled_mail_(enabled_ && scheduled_mail),
      window_(window),
      wake_(std::move(wake)),
      free_permits_(permits),
      state_(nodes, kActiveWaiting),
      clock_(nodes, 0.0),
      resuming_(nodes, 0),
      awaits_work_(nodes, 0),
      mail_pending_(nodes, 0),
      retired_(nodes, 0),
      granted_(new std::atomic<bool>[nodes]),
      serving_(new std::atomic<bool>[nodes]) {
  for (std::uint32_t i = 0; i < nodes; ++i) {
    granted_[i].store(false, std::memory_order_relaxed);
    serving_[i].store(false, std::memory_order_relaxed);
  }
}

double Scheduler::clock_limit() const {
  double active = std::numeric_limits<double>::infinity(), work = active;
  for (std::size_t j = 0; j < state_.size(); ++j) {
    if (state_[j] == kInactive) continue;
    active = std::min(active, clock_[j]);
    if (state_[j] == kAwaiting && awaits_work_[j]) work = std::min(work, clock_[j]);
  }
  return std::min(active + window_, work);
}

void Scheduler::grant(std::uint32_t node, bool compute, std::vector<std::uint32_t>& wake) {
  --free_permits_;
  if (mail_pending_[node]) {
    mail_pending_[node] = false;
    --mail_count_;
  }
  // release: the grantee's acquire load in its wait sees the permit.
  if (compute) {
    resuming_[node] = false;
    state_[node] = kRunning;
    ++compute_grants_;
    granted_[node].store(true, std::memory_order_release);
  } else {
    ++service_grants_;
    serving_[node].store(true, std::memory_order_release);
  }
  wake.push_back(node);
}

void Scheduler::grant_eligible(std::vector<std::uint32_t>& wake) {
  const double limit = clock_limit();
  const std::size_t n = state_.size();
  while (free_permits_ > 0) {
    // 1. A node resuming inside its work unit, whatever its clock. 2. Mail
    // of a sleeping node (a compute permit if it may run anyway). 3. The
    // lowest queued node, if it may run.
    std::int64_t best = -1;
    for (std::size_t j = 0; j < n; ++j) {
      if (state_[j] != kActiveWaiting || serving_[j].load(std::memory_order_relaxed)) continue;
      if (best < 0 || (resuming_[j] && !resuming_[std::size_t(best)]) ||
          (resuming_[j] == resuming_[std::size_t(best)] && clock_[j] < clock_[std::size_t(best)]))
        best = std::int64_t(j);
    }
    if (best >= 0 && resuming_[std::size_t(best)]) {
      grant(std::uint32_t(best), true, wake);
      continue;
    }
    if (mail_count_ > 0) {
      for (std::size_t k = 0; k < n; ++k) {
        const std::size_t j = (next_mail_ + k) % n;
        if (!mail_pending_[j]) continue;
        next_mail_ = std::uint32_t((j + 1) % n);  // round robin: no node's mail waits behind a chatty one's
        grant(std::uint32_t(j), state_[j] == kActiveWaiting && clock_[j] <= limit, wake);
        break;
      }
      continue;
    }
    if (best < 0 || clock_[std::size_t(best)] > limit) return;
    grant(std::uint32_t(best), true, wake);
  }
}

void Scheduler::take_permit_back(std::uint32_t node) {
  if (state_[node] == kRunning) {
    granted_[node].store(false, std::memory_order_relaxed);
    ++free_permits_;
  }
  if (serving_[node].load(std::memory_order_relaxed)) {
    serving_[node].store(false, std::memory_order_relaxed);
    ++free_permits_;
  }
}

void Scheduler::note_mail(std::uint32_t node, bool force) {
  if (!scheduled_mail_) return;
  std::vector<std::uint32_t> wake;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (state_[node] == kRunning || serving_[node].load(std::memory_order_relaxed) || retired_[node]) return;
    if (force) {
      grant(node, false, wake);  // may take free_permits_ below 0: it comes back at end_service
    } else {
      if (mail_pending_[node]) return;
      mail_pending_[node] = true;
      ++mail_count_;
      grant_eligible(wake);
    }
  }
  for (std::uint32_t j : wake) wake_(j);
}

void Scheduler::end_service(std::uint32_t node) {
  if (!scheduled_mail_) return;
  std::vector<std::uint32_t> wake;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!serving_[node].load(std::memory_order_relaxed)) return;
    serving_[node].store(false, std::memory_order_relaxed);
    ++free_permits_;
    grant_eligible(wake);
  }
  for (std::uint32_t j : wake)
    if (j != node) wake_(j);
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
    take_permit_back(node);  // a service permit: the node now asks to compute
    clear_mail(node);        // it is awake and polls its mailbox before it sleeps
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
    if (clock > clock_limit()) {
      // Too far ahead of someone active or awaiting work: give the permit back and queue.
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
  std::size_t n_running = 0, n_queued = 0, n_awaiting = 0, n_serving = 0;
  for (std::size_t j = 0; j < state_.size(); ++j) {
    n_serving += serving_[j].load(std::memory_order_relaxed);
    if (state_[j] == kRunning && n_running++ < 8) running += fmt::format(" {}@{:.6g}", j, clock_[j]);
    if (state_[j] == kActiveWaiting && n_queued++ < 8) queued += fmt::format(" {}@{:.6g}", j, clock_[j]);
    if (state_[j] == kAwaiting && n_awaiting++ < 8)
      awaiting += fmt::format(" {}@{:.6g}{}", j, clock_[j], awaits_work_[j] ? " (work)" : "");
  }
  return fmt::format("scheduler: {} free permits, {} running [{} ], {} queued [{} ], {} awaiting a reply [{} ], "
                     "{} serving mail, {} with mail waiting for service, window {:.3g} s",
                     free_permits_, n_running, running, n_queued, queued, n_awaiting, awaiting, n_serving,
                     mail_count_, window_);
}

void Scheduler::await_reply(std::uint32_t node, double clock, Awaited what) {
  if (!enabled_) return;
  std::vector<std::uint32_t> wake;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    take_permit_back(node);
    clear_mail(node);
    state_[node] = kAwaiting;
    awaits_work_[node] = what == Awaited::kWork;
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
    if (state_[node] == kInactive && !serving_[node].load(std::memory_order_relaxed)) return;
    take_permit_back(node);
    clear_mail(node);
    state_[node] = kInactive;
    grant_eligible(wake);
  }
  for (std::uint32_t j : wake) wake_(j);
}

void Scheduler::retire(std::uint32_t node) {
  if (!enabled_) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    retired_[node] = true;
  }
  release(node);
}

void Scheduler::clear_mail(std::uint32_t node) {
  if (mail_pending_[node]) {
    mail_pending_[node] = false;
    --mail_count_;
  }
}

}  // namespace raynode::nodes
