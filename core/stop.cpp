#include "core/stop.h"

#include <mutex>

namespace raynode::core {

namespace {
std::mutex g_message_mutex;
std::string g_message;  // guarded by g_message_mutex
}  // namespace

void request_stop(const std::string& message) {
  {
    std::lock_guard<std::mutex> lock(g_message_mutex);
    if (g_message.empty()) g_message = message;
  }
  // Release: a poller that sees the flag and then locks finds the message.
  detail::g_stop_requested.store(true, std::memory_order_release);
}

std::string stop_message() {
  std::lock_guard<std::mutex> lock(g_message_mutex);
  return g_message.empty() ? std::string("stopped") : g_message;
}

void clear_stop_request() {
  std::lock_guard<std::mutex> lock(g_message_mutex);
  g_message.clear();
  detail::g_stop_requested.store(false, std::memory_order_release);
}

}  // namespace raynode::core
