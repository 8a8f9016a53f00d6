// The network cost model of the emulated machine (docs/architecture.md, "Virtual
// time"): a message of b bytes crossing h links, sent at the sender's clock
// t, costs the sender send_overhead of CPU time and arrives
//     arrival = t + send_overhead + latency + b x per_byte + h x per_hop
// in virtual seconds (later under link contention, links.h). The receiver's
// clock becomes max(own, arrival). A reply sent by an interrupt handler
// departs when its service (service + send_overhead) ends.
//
// Presets (`--network`):
//  * none    — free, instantaneous messages: isolates computation.
//  * ipsc2   — the paper's Intel iPSC/2, scaled to this machine. The paper
//              (section "Results with control-oriented parallelization")
//              gives 0.9 MB/s for 1 KiB messages and a 2.75 MB/s peak. Read
//              as start-up + bytes / peak, that is
//                per_byte = 1 / 2.75e6 s           = 0.364 us/B
//                start-up = 1024/0.9e6 - 1024/2.75e6 = 0.765 ms,
//              of which the sender's processor spends 0.35 ms in the message
//              software (send_overhead, the zero-byte latency: Arlauskas
//              1988, below) and the rest, 0.415 ms, is the wire's latency;
//              and we add 10 us per hop (the paper gives none; Direct-Connect
//              circuit switching makes it ~1% of the start-up). Links contend
//              (`contention`, links.h): a Direct-Connect circuit holds its
//              links while the message streams, full duplex, 2.8 MB/s each
//              way (S. F. Nugent, "The iPSC/2 Direct-Connect communications
//              technology", Proc. 3rd Conf. on Hypercube Concurrent Computers
//              and Applications, 1988). To keep the
//              paper's ratio of page transfer to ray computation, every cost
//              is multiplied by
//                scale = (this machine's seconds per ray) / (iPSC/2 seconds per ray),
//              where the iPSC/2 traced Teapot's 1,397,473 rays in 3:12:02 on
//              one node (Tables 2 and 3): 8.245 ms per ray. This machine's
//              seconds per ray are measured by calibrate_seconds_per_ray()
//              (one thread tracing teapot:8 at 64x64, best of 3) or given with
//              --network-scale. A 1 KiB page then costs 0.138 ray-times, as
//              on the iPSC/2.
//  * cluster — a modern cluster, unscaled: 1.5 us latency, 12.5 GB/s (100
//              Gb/s InfiniBand), 0.1 us per hop.
// Every preset also names the cost of serving a message at interrupt level
// (`service`, e.g. a page request at its home node): ipsc2 charges 0.1 ms
// (about a 1 KiB copy at the 80386's ~10 MB/s memory bandwidth), scaled.
// ipsc2 charges the same for the faulting node's own work on a page fault
// (`fault`: the trap, the reply's 1 KiB copy into a frame, the table),
// under the model clock: the two ends of a page's transfer then cost the
// iPSC/2's share of a ray (~0.012 ray-times) alike. Under the other presets
// a fault's own work is the cost model's (core/cost_model.h: ~0.15 us, a
// modern node's, some 0.8 ray-times) or, under the CPU clock, measured.
#pragma once

#include <cstdint>
#include <string>

#include "core/cost_model.h"

namespace raynode::nodes {

/// iPSC/2 seconds per ray on one node (Teapot, Tables 2 and 3): 11522 s / 1,397,473 rays.
inline constexpr double kIpsc2SecondsPerRay = 11522.0 / 1397473.0;
/// The iPSC/2 sender's CPU time per message: the zero-byte message latency
/// of its message software, 350 us (E. Arlauskas, "iPSC/2 system: a second
/// generation hypercube", Proc. 3rd Conf. on Hypercube Concurrent Computers
/// and Applications, 1988: the release target; beta software measured 490
/// us), counted as the sending processor's own time (a zero-byte message
/// has no wire time to speak of).
inline constexpr double kIpsc2SendOverheadS = 350e-6;

struct NetworkModel {
  std::string name = "none";
  double latency_s = 0;   ///< start-up cost per message, virtual seconds
  double per_byte_s = 0;  ///< virtual seconds per byte on the wire
  double per_hop_s = 0;   ///< virtual seconds per link crossed
  double service_s = 0;   ///< receiver's cost to serve a message at interrupt level
  /// The sender's own CPU time per message: the message software's part of
  /// the start-up, spent on the node's processor before the message leaves
  /// (charged as busy time); the wire's start-up is latency_s besides it.
  double send_overhead_s = 0;
  /// The message software's time for one look for mail (NodeContext::poll,
  /// found or not), charged as busy time on machines of more than one
  /// node, in the emulator only (under a transport the real look is in the
  /// rank's own time): an MPI rank's probe of its peers and the library's
  /// progress engine, where the emulator's own look is one atomic load.
  double poll_s = 0;
  /// A page fault's own work at the faulting node under the model clock,
  /// virtual seconds; < 0: the cost model's (CostFeature::kPageFault).
  double fault_s = -1;
  /// Under the model clock, the work of each access to a page held in a
  /// node's cache (not a home page), virtual seconds: a shared virtual
  /// memory in software looks the page up and updates its LRU recency on
  /// every such access, which home pages and one node's run never pay.
  /// >= 0 replaces the cost model's figure (CostFeature::kCachePageAccess,
  /// 0 unless a machine description's cost_model sets it); < 0: the cost
  /// model's, as for fault_s. Unset (< 0) in every preset: no source gives
  /// the iPSC/2 svm's figure (docs/results.md, "Each access to a cached
  /// page", sweeps it); a machine description may set it.
  double cache_access_s = -1;
  /// Link contention (links.h): a message holds its route's links while it
  /// streams, and waits for a link another message holds. Off: links are
  /// never busy (a message costs message_time whatever else is sent).
  bool contention = false;
  double scale = 1;       ///< the factor applied to the preset's real figures

  /// An interrupt handler's time to serve a request and send its reply.
  double reply_service_s() const { return service_s + send_overhead_s; }
  /// Transfer time of `bytes` over `hops` links, virtual seconds (after the
  /// sender's send_overhead_s).
  double message_time(std::uint64_t bytes, std::uint32_t hops) const {
    return latency_s + double(bytes) * per_byte_s + double(hops) * per_hop_s;
  }
};

/// A preset by name ("none", "ipsc2", "cluster"). `seconds_per_ray` is this
/// machine's tracing speed (used by ipsc2 only; <= 0 means calibrate now:
/// with `model`, the model clock's seconds per ray, else measured CPU time).
/// Throws std::invalid_argument for an unknown name.
NetworkModel make_network(const std::string& name, double seconds_per_ray = 0,
                          const core::CostModel* model = nullptr);

/// Seconds per ray of the sequential tracer on this machine, one thread:
/// teapot:8 at 64x64 pixels, best of 3 (about 0.1 s in all).
double calibrate_seconds_per_ray();
/// The same render's seconds per ray under the cost model (the model
/// clock's): deterministic.
double model_seconds_per_ray(const core::CostModel& model);

}  // namespace raynode::nodes
