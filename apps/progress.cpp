#include "apps/progress.h"

#include <fmt/core.h>
#include <unistd.h>

#include <cstdio>

namespace raynode::apps {

namespace {
constexpr auto kDelay = std::chrono::seconds(1);           // silent before this
constexpr auto kRefresh = std::chrono::milliseconds(200);  // then redraw this often
}  // namespace

std::string short_count(std::uint64_t n) {
  if (n < 1000) return fmt::format("{}", n);
  if (n < 1000000) return fmt::format("{}k", n / 1000);
  if (n < 10000000) return fmt::format("{:.1f}M", double(n) / 1e6);
  return fmt::format("{}M", n / 1000000);
}

std::string progress_text(const char* what, std::uint64_t done, std::uint64_t total, double seconds) {
  const int pct = total ? int(done * 100 / total) : 100;
  std::string text =
      fmt::format("{}: {}% ({}/{} pixels) {:.1f} s", what, pct, short_count(done), short_count(total), seconds);
  // The time left, at the rate so far, once there is a rate to go by.
  if (done > 0 && done < total && seconds >= 1.0)
    text += fmt::format(", ~{:.0f} s left", seconds * double(total - done) / double(done));
  return text;
}

ProgressLine::ProgressLine(const char* what, const std::atomic<std::uint64_t>& counter, std::uint64_t total,
                           bool enabled)
    : what_(what), counter_(counter), total_(total), start_(std::chrono::steady_clock::now()) {
  if (enabled && isatty(fileno(stderr))) thread_ = std::thread([this] { run(); });
}

ProgressLine::~ProgressLine() { finish(); }

void ProgressLine::finish() {
  if (!thread_.joinable()) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_one();
  thread_.join();
  if (shown_) {
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    fmt::print(stderr, "\r{:<64}\n", progress_text(what_, counter_.load(std::memory_order_relaxed), total_, s));
    std::fflush(stderr);
  }
}

void ProgressLine::run() {
  std::unique_lock<std::mutex> lock(mutex_);
  if (wake_.wait_until(lock, start_ + kDelay, [this] { return stop_; })) return;
  for (;;) {
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    // Pad with spaces so a shorter line fully covers the previous one.
    fmt::print(stderr, "\r{:<64}", progress_text(what_, counter_.load(std::memory_order_relaxed), total_, s));
    std::fflush(stderr);
    shown_ = true;
    if (wake_.wait_for(lock, kRefresh, [this] { return stop_; })) return;
  }
}

}  // namespace raynode::apps
