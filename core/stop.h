// A process-wide stop request: how `--timeout` reaches
// work that has no clock of its own (reading and parsing a scene,
// triangulating polygons, tessellating, building the grid, and every ray of
// a render, however deep its reflection tree).
//
// Place in the data flow: the CLI's watchdog (apps/) calls request_stop()
// when the deadline passes; long loops anywhere below poll stop_requested()
// (one relaxed atomic load, no clock read) and leave by throw_if_stopped(),
// which throws StopError with the watchdog's message. A global on purpose:
// it is the one piece of state every layer may read, like a signal.
// Header-only, so that nodes/ (built alone for its ThreadSanitizer test)
// can poll it without linking core.
#pragma once

#include <atomic>
#include <mutex>
#include <stdexcept>
#include <string>
#include <string_view>

namespace raynode::core {

/// Thrown by throw_if_stopped() once a stop was requested. what(): the
/// requester's message, then ": stopped while <doing>".
class StopError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

namespace detail {
inline std::atomic<bool> g_stop_requested{false};
inline std::mutex g_stop_mutex;
inline std::string g_stop_message;  // guarded by g_stop_mutex
}  // namespace detail

/// True once request_stop() was called. Wait-free; any thread; cheap enough
/// for once per ray.
inline bool stop_requested() noexcept { return detail::g_stop_requested.load(std::memory_order_relaxed); }

/// Asks every loop that polls stop_requested() to stop. `message` says why,
/// e.g. "the run did not finish within 5 s (--timeout)"; the first caller's
/// message is kept. Thread-safe; not async-signal-safe (it stores a string).
inline void request_stop(const std::string& message) {
  {
    std::lock_guard<std::mutex> lock(detail::g_stop_mutex);
    if (detail::g_stop_message.empty()) detail::g_stop_message = message;
  }
  // Release: a poller that sees the flag and then locks finds the message.
  detail::g_stop_requested.store(true, std::memory_order_release);
}

/// The first request_stop() message ("stopped" when none was given). Thread-safe.
inline std::string stop_message() {
  std::lock_guard<std::mutex> lock(detail::g_stop_mutex);
  return detail::g_stop_message.empty() ? std::string("stopped") : detail::g_stop_message;
}

/// Throws StopError("<message>: stopped while <doing>") when a stop was
/// requested; otherwise returns at the cost of stop_requested(). `doing`
/// names the phase for the user, e.g. "reading 'scene.nff'".
inline void throw_if_stopped(std::string_view doing) {
  if (stop_requested()) [[unlikely]] {
    throw StopError(stop_message() + ": stopped while " + std::string(doing));
  }
}

/// Clears the request (tests only: a process that was asked to stop exits).
inline void clear_stop_request() {
  std::lock_guard<std::mutex> lock(detail::g_stop_mutex);
  detail::g_stop_message.clear();
  detail::g_stop_requested.store(false, std::memory_order_release);
}

}  // namespace raynode::core
