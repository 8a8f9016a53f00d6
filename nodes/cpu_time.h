// The calling thread's own CPU time (CLOCK_THREAD_CPUTIME_ID): what a node's
// virtual clock advances by while it computes, so that oversubscribed node
// threads still measure only their own work (docs/architecture.md, "Virtual time").
#pragma once

#include <ctime>

namespace raynode::nodes {

/// CPU seconds consumed by the calling thread so far (nanosecond resolution).
inline double thread_cpu_seconds() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

}  // namespace raynode::nodes
