#include "apps/watchdog.h"

#include <fmt/core.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <thread>

#include "apps/output_files.h"
#include "core/stop.h"

namespace raynode::apps {

namespace {
using Clock = std::chrono::steady_clock;
Clock::time_point g_start = Clock::now();  // replaced by mark_process_start()
bool g_started = false;
}  // namespace

void mark_process_start() { g_start = Clock::now(); }

double seconds_since_start() { return std::chrono::duration<double>(Clock::now() - g_start).count(); }

void start_timeout_watchdog(double timeout_s) {
  if (!(timeout_s > 0) || g_started) return;
  g_started = true;
  const Clock::time_point deadline =
      g_start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(timeout_s));
  const std::string message = fmt::format("the run did not finish within {} s (--timeout)", timeout_s);
  std::thread([deadline, message] {
    std::this_thread::sleep_until(deadline);
    core::request_stop(message);
    std::this_thread::sleep_until(deadline + std::chrono::duration_cast<Clock::duration>(
                                                 std::chrono::duration<double>(kTimeoutGraceS)));
    // The command did not end by itself: end it here.
    remove_temporaries_now();
    const std::string line = "raynode: error: " + message + "; stopped\n";
    (void)!::write(2, line.data(), line.size());
    ::_exit(1);
  }).detach();
}

}  // namespace raynode::apps
