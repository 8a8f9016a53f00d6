// A progress line on stderr for long renders:
//   render: 45% (118k/262k pixels) 1.9 s, ~2 s left
// refreshed in place with '\r' by a background thread that polls an atomic
// pixel counter the renderer bumps once per row or tile
// (core::RenderParams::progress). In the node modes the counter is the
// pixels the host has received (dataflow: the pixels whose first eye ray a
// node has started). Nothing is printed during the first
// second, when stderr is not a terminal (isatty), or when disabled (--quiet),
// so short renders, pipes and logs stay clean. The renderer never waits for
// this thread: the image and the render time are unaffected.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>

namespace raynode::apps {

/// "118k", "1.2M", "950": a count in at most 4-5 characters.
std::string short_count(std::uint64_t n);

/// The text of one progress line (no '\r', no newline).
std::string progress_text(const char* what, std::uint64_t done, std::uint64_t total, double seconds);

/// Shows `counter` / `total` on stderr while alive. Construct right before
/// the render, call finish() (or destroy) right after. Thread-safe: the
/// counter may be bumped from any thread.
class ProgressLine {
 public:
  /// `enabled` = false (e.g. --quiet) makes this a no-op; it is also a no-op
  /// when stderr is not a TTY. `what` labels the line ("render").
  ProgressLine(const char* what, const std::atomic<std::uint64_t>& counter, std::uint64_t total, bool enabled);
  ~ProgressLine();
  ProgressLine(const ProgressLine&) = delete;
  ProgressLine& operator=(const ProgressLine&) = delete;

  /// Stops the thread; if a line was shown, prints the final count and a
  /// newline. Idempotent.
  void finish();

 private:
  void run();

  const char* what_;
  const std::atomic<std::uint64_t>& counter_;
  std::uint64_t total_;
  std::chrono::steady_clock::time_point start_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  bool shown_ = false;
  std::thread thread_;
};

}  // namespace raynode::apps
