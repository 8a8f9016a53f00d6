// Virtual-time scheduling of the node threads: at most K of them compute at
// once (K = the host's hardware threads), and a node may compute only while
// its virtual clock is within `window` of the slowest active node's. Without
// it, which emulated node runs is up to the operating system, so a node that
// happens to get more CPU races ahead in virtual time and decisions driven
// by message order (who steals work from whom) follow the host's thread
// scheduling instead of the emulated machine's time: with 64 nodes on 2
// cores the measured efficiency of a perfectly balanced image fell to ~35%.
// With it, the emulation behaves like a discrete-event simulation that keeps
// the nodes' clocks together, and only K threads are runnable, so many
// nodes cost little more wall time than K.
//
// States: running (holds a permit), active-waiting (wants to compute;
// queued with its clock), awaiting a reply (blocked for the answer to its
// own request — a work grant, a page — which will let it go on at about its
// clock: it holds the others back like an active node, without a permit),
// inactive (blocked with nothing to expect, or its work is over: it does
// not hold the others back). A queued node gets a permit when one is free
// and its clock is <= min(active and awaiting clocks) + window, lowest
// clock first. Every node starts active-waiting at clock 0.
//
// A node awaiting a work grant holds back harder: no node may compute past
// its clock (window 0). A work request's answer depends on the state of
// the pools it finds, and a node that has run ahead in virtual time has
// already taken the items that, at the request's arrival, it still held:
// it forwards the request, and the requester ends early while work is
// left (measured: Tetra9 at 64 nodes, half grants, nodes ended 0-180 us
// before the last, 4-5% of the work; the requests went round nodes up to
// 120 us ahead of them). A page request's answer does not depend on when
// it is served, so a node awaiting a page holds back by `window` only.
//
// Why awaiting holds back: a node whose requests are answered in wall time
// by a busier node would otherwise let that node run ahead alone, handing
// out work at virtual times long past (measured: a replicated render at 16
// nodes ended with 15 nodes done at 20 ms and one at 30 ms, efficiency
// 72%). A node that waits for permission still serves its mail, so the
// awaited reply always comes.
//
// Protocol (node side, see work.h's farm loop): before computing, try_run;
// if refused, wait for mail or for the permit (granted by waking the node's
// mailbox) and ask again. Between work units, yield_point: a node more than
// `window` ahead of an active node gives its permit back. release when the
// node blocks for mail or its work ends.
//
// Mail service (`scheduled_mail`; MachineParams::scheduled_mail says for
// which modes): a node that holds no permit is not woken per message. A
// sender that finds the destination without a permit calls note_mail(); the
// node gets a service permit — one of the K, its role above unchanged — as
// soon as one is free, before any queued compute, and serves everything
// that came meanwhile in one wake-up. A message to a sleeping node then
// costs a hand-over on a core that was going to switch anyway, not a
// preemption of a computing node, and a node that several messages reach
// while it sleeps serves them all at once. A mailbox found half full or
// full is served at once, one permit beyond K if need be (note_mail's
// `force`): its owner must drain it before senders block or spill. Virtual
// time is untouched: a node without a permit does not move its clock, and
// every message carries its own arrival stamp. end_service() (or any call
// below) gives the service permit back.
//
// Thread safety: all members are called by node threads (and note_mail by
// the host); one mutex guards the state (an O(nodes) scan per work unit).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace raynode::nodes {

/// What a node awaiting a reply waits for (Scheduler::await_reply).
enum class Awaited : std::uint8_t {
  kReply,  ///< a reply that does not depend on when it is served (a page): others may run `window` ahead
  kWork,   ///< a work grant, or its request's return: no node computes past the awaiting node's clock
};

class Scheduler {
 public:
  /// `wake(node)` wakes a node's mailbox wait. permits >= 1; window >= 0
  /// virtual seconds; permits = 0, window < 0 or a single node disables
  /// scheduling (every call grants).
  /// `scheduled_mail`: serve sleeping nodes' mail with service permits.
  Scheduler(std::uint32_t nodes, std::uint32_t permits, double window, std::function<void(std::uint32_t)> wake,
            bool scheduled_mail = false);

  bool enabled() const { return enabled_; }
  /// Are sleeping nodes woken by the scheduler's service permits rather than
  /// per message (see "Mail service" above)? Only when enabled().
  bool scheduled_mail() const { return scheduled_mail_; }
  /// Does `node` hold a permit? If not, queues it with `clock` and takes a
  /// permit if one is free and the node may run; else returns false.
  /// `resume`: the node stopped inside a work unit (a page fault) and
  /// takes the next free permit whatever its clock — its wait for the
  /// permit sets other nodes' messages aside, so it must not be held back
  /// by a node that awaits one of them.
  bool try_run(std::uint32_t node, double clock, bool resume = false);
  /// Between work units: returns true to go on, or false after giving the
  /// permit back because `clock` is more than `window` ahead of an active
  /// node (the caller is then queued).
  bool yield_point(std::uint32_t node, double clock);
  /// Gives up the permit and becomes inactive (blocking for mail, or done).
  void release(std::uint32_t node);
  /// The node's thread has ended: release(), and no service permit is ever
  /// granted to it again.
  void retire(std::uint32_t node);
  /// Gives up the permit while awaiting the reply to a request: the node's
  /// `clock` still holds the others back until its next try_run(), by
  /// `window` or, awaiting work, by nothing (see "A node awaiting a work
  /// grant" above).
  void await_reply(std::uint32_t node, double clock, Awaited what = Awaited::kReply);
  /// A message was put in the mailbox of `node`, which held no permit when
  /// the sender looked: it gets a service permit when one is free (at once
  /// if one is). No effect on a node that holds a permit. `force`: the
  /// sender is blocked on the node's full mailbox, perhaps holding a permit
  /// itself: the node gets a service permit at once, one more than K if
  /// none is free, so that it drains its mailbox (no deadlock of full
  /// mailboxes behind taken permits).
  void note_mail(std::uint32_t node, bool force = false);
  /// Gives a service permit back (the node served its mail and sleeps).
  void end_service(std::uint32_t node);
  /// The flag a waiting node's mailbox wait also watches: set when a
  /// (compute) permit is granted to it.
  const std::atomic<bool>& granted_flag(std::uint32_t node) const { return granted_[node]; }
  /// Set while the node holds a service permit.
  const std::atomic<bool>& serving_flag(std::uint32_t node) const { return serving_[node]; }

  /// Compute permits taken back from nodes a window ahead.
  std::uint64_t handoffs() const { return handoffs_; }
  /// Compute permits granted to queued nodes (the first try_run's included).
  std::uint64_t compute_grants() const { return compute_grants_; }
  /// Service permits granted to sleeping nodes with mail.
  std::uint64_t service_grants() const { return service_grants_; }
  /// One line on the state (free permits, running and queued nodes with
  /// their clocks), for the watchdog's error message.
  std::string describe();

 private:
  enum State : char { kInactive, kActiveWaiting, kRunning, kAwaiting };
  /// The clock up to which a node may compute: the smallest clock over
  /// running, queued and awaiting nodes plus the window, or the smallest
  /// clock of a node awaiting work if lower (+inf if none). Lock held.
  double clock_limit() const;
  /// Hands free permits to eligible queued nodes, lowest clock first;
  /// appends them to `wake`. Lock held.
  void grant_eligible(std::vector<std::uint32_t>& wake);
  /// Takes back whatever permit `node` holds (compute or service). Lock held.
  void take_permit_back(std::uint32_t node);
  /// Grants `node` a compute (or else a service) permit. Lock held.
  void grant(std::uint32_t node, bool compute, std::vector<std::uint32_t>& wake);
  /// Forgets that `node` has mail waiting for service. Lock held.
  void clear_mail(std::uint32_t node);

  bool enabled_;
  bool scheduled_mail_;
  double window_;
  std::function<void(std::uint32_t)> wake_;
  std::mutex mutex_;
  std::int64_t free_permits_;  ///< may go below 0 while forced service permits are out (note_mail)
  std::vector<State> state_;
  std::vector<double> clock_;
  std::vector<char> resuming_;      ///< queued by try_run(..., resume = true)
  std::vector<char> awaits_work_;   ///< kAwaiting with Awaited::kWork
  std::vector<char> mail_pending_;  ///< has mail, waits for a service permit
  std::vector<char> retired_;       ///< its thread has ended
  std::uint32_t mail_count_ = 0;    ///< nodes with mail_pending_
  std::unique_ptr<std::atomic<bool>[]> granted_;  ///< holds a compute permit (read lock-free by its owner)
  std::unique_ptr<std::atomic<bool>[]> serving_;  ///< holds a service permit (read lock-free by its owner)
  std::uint32_t next_mail_ = 0;     ///< where the round-robin search for pending mail starts
  std::uint64_t handoffs_ = 0;
  std::uint64_t compute_grants_ = 0;
  std::uint64_t service_grants_ = 0;
};

}  // namespace raynode::nodes
