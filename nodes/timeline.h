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
// Periods that touch are merged, and memory is bounded: past kMaxPeriods
// separate periods the earlier half is forgotten, so a request that far
// behind finds the resource free there (optimistic by at most the forgotten
// periods' overlap with it; the scheduler's window keeps real bookings close
// to each other in virtual time). A flat sorted array: binary search in
// contiguous memory, and a booking allocates nothing once it has grown.
#pragma once

#include <algorithm>
#include <cstddef>
#include <iterator>
#include <vector>

namespace raynode::nodes {

class BusyTimeline {
 public:
  /// Periods kept before the earlier half is forgotten.
  static constexpr std::size_t kMaxPeriods = 4096;

  /// The start of the first gap of at least `length` virtual seconds at or
  /// after `earliest`; books nothing.
  double first_gap(double earliest, double length) const {
    double start = earliest;
    auto next = after(start);
    if (next != busy_.begin()) start = std::max(start, std::prev(next)->end);
    while (next != busy_.end() && next->start < start + length) start = std::max(start, (next++)->end);
    return start;
  }
  /// Books [start, start + length), which must be free (first_gap's answer),
  /// merged with the busy periods it touches (a stream of back-to-back
  /// periods is then one, which first_gap crosses in one step). A
  /// zero-length period books nothing.
  void book(double start, double length) {
    if (!(length > 0)) return;
    const double end = start + length;
    auto next = std::lower_bound(busy_.begin(), busy_.end(), start,
                                 [](const Period& p, double t) { return p.start < t; });
    const bool joins_prev = next != busy_.begin() && std::prev(next)->end >= start;
    const bool joins_next = next != busy_.end() && next->start <= end;
    if (joins_prev && joins_next) {
      std::prev(next)->end = std::max(next->end, end);
      busy_.erase(next);
    } else if (joins_prev) {
      std::prev(next)->end = std::max(std::prev(next)->end, end);
    } else if (joins_next) {
      next->start = start;
      next->end = std::max(next->end, end);
    } else {
      busy_.insert(next, Period{start, end});
    }
    if (busy_.size() > kMaxPeriods) busy_.erase(busy_.begin(), busy_.begin() + std::ptrdiff_t(kMaxPeriods / 2));
  }
  /// Frees [start, start + length) again (a booking that was not used), if
  /// it is still kept.
  void cancel(double start, double length) {
    const double end = start + length;
    auto it = after(start);
    if (it == busy_.begin()) return;
    --it;
    if (!(it->end >= end)) return;  // not booked (forgotten)
    const Period whole = *it;
    if (whole.start < start && end < whole.end) {  // a hole in the middle: two periods
      it->end = start;
      busy_.insert(std::next(it), Period{end, whole.end});
    } else if (whole.start < start) {
      it->end = start;
    } else if (end < whole.end) {
      it->start = end;
    } else {
      busy_.erase(it);
    }
  }
  /// first_gap then book; returns the start.
  double take(double earliest, double length) {
    const double start = first_gap(earliest, length);
    book(start, length);
    return start;
  }
  std::size_t periods() const { return busy_.size(); }

 private:
  struct Period {
    double start, end;
  };
  /// The first period starting after `t`.
  std::vector<Period>::const_iterator after(double t) const {
    return std::upper_bound(busy_.begin(), busy_.end(), t, [](double v, const Period& p) { return v < p.start; });
  }
  std::vector<Period>::iterator after(double t) {
    return std::upper_bound(busy_.begin(), busy_.end(), t, [](double v, const Period& p) { return v < p.start; });
  }
  std::vector<Period> busy_;  ///< sorted by start, disjoint and not touching (a flat array: few, cache-resident)
};

}  // namespace raynode::nodes
