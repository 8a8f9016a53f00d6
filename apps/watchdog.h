// The --timeout watchdog: a hard limit on a whole command, counted from
// process start, over reading the scene, tessellating, building the grid,
// rendering and writing.
//
// Place in the data flow: main() marks the start; a command with --timeout
// starts the watchdog before its first step. At the deadline it asks every
// loop to stop (core/stop.h), which ends the command with one message and
// exit status 1 through the usual error path; if the command has not ended
// after a short grace period (a blocking system call, a loop that does not
// poll), the watchdog prints the message, removes the temporaries
// (apps/output_files.h) and exits with status 1 itself.
#pragma once

namespace raynode::apps {

/// Seconds of grace between the stop request and the forced exit.
inline constexpr double kTimeoutGraceS = 1.0;

/// Records the process start; main() calls it first.
void mark_process_start();

/// Wall seconds since mark_process_start().
double seconds_since_start();

/// Starts the watchdog for `timeout_s` wall seconds from process start (0 =
/// none: returns at once). Its message: "the run did not finish within
/// <timeout_s> s (--timeout)". At most one per process; later calls are
/// ignored.
void start_timeout_watchdog(double timeout_s);

}  // namespace raynode::apps
