// Busy periods of one resource of the emulated machine in virtual time: a
// node's interrupt handler (NodeContext::serve_interrupt) or a network link
// (links.h). A new period takes the first gap long enough for it at or
// after its earliest start (first fit).
//
// Why first fit and not "after the last booking": node threads book in
// real-time order, which is not their virtual-time order (the scheduler
// keeps clocks within a window, not in lockstep), so a request booked late
// may belong before earlier bookings. Queueing it behind them would be an
// artefact of the host's thread scheduling (docs/architecture.md, "Virtual
// time").
//
// Memory is bounded: past kMaxPeriods the earlier half is forgotten, so a
// request that far behind finds the resource free there (optimistic by at
// most the forgotten periods' overlap with it; the scheduler's window keeps
// real bookings close to each other in virtual time).
#pragma once

#include <algorithm>
#include <cstddef>
#include <iterator>
#include <map>

namespace raynode::nodes {

class BusyTimeline {
 public:
  /// Periods kept before the earlier half is forgotten.
  static constexpr std::size_t kMaxPeriods = 1u << 14;

  /// The start of the first gap of at least `length` virtual seconds at or
  /// after `earliest`; books nothing.
  double first_gap(double earliest, double length) const {
    double start = earliest;
    auto next = busy_.upper_bound(start);
    if (next != busy_.begin()) start = std::max(start, std::prev(next)->second);
    while (next != busy_.end() && next->first < start + length) start = std::max(start, (next++)->second);
    return start;
  }
  /// Books [start, start + length), which must be free (first_gap's answer).
  /// A zero-length period books nothing.
  void book(double start, double length) {
    if (!(length > 0)) return;
    busy_.emplace(start, start + length);
    if (busy_.size() > kMaxPeriods) busy_.erase(busy_.begin(), std::next(busy_.begin(), std::ptrdiff_t(kMaxPeriods / 2)));
  }
  /// Takes back the period booked at `start` (if it is still kept).
  void cancel(double start) { busy_.erase(start); }
  /// first_gap then book; returns the start.
  double take(double earliest, double length) {
    const double start = first_gap(earliest, length);
    book(start, length);
    return start;
  }
  std::size_t periods() const { return busy_.size(); }

 private:
  std::map<double, double> busy_;  ///< start -> end, disjoint
};

}  // namespace raynode::nodes
