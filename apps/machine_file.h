// `--machine NAME|FILE`: a description of the emulated distributed-memory
// machine, read before the other machine options so that those given on the
// command line override it. `ipsc2` is built in (docs/machines/ipsc2.json is
// the same machine as a file, and the example of the format); a FILE is JSON:
//
//   {"name": "...", "about": "...",             (both optional, free text)
//    "node_memory": "4MiB",                     (bytes with a unit)
//    "page_size": 1024,                         (svm page, bytes)
//    "topology": "hypercube|ring|torus",
//    "clock": "cpu|model",
//    "corun_slowdown": x,                       (>= 1: under the model clock, the factor on
//                                                a node's work when more than one node runs;
//                                                nodes sharing a host's cores and memory)
//    "cost_model": {"primary_ray": s, ...},    (the model clock's unit costs by name,
//                                                seconds; those not given keep the
//                                                built-in model's: core/cost_model.h)
//    "network": "none|ipsc2|cluster"            (a preset, or its figures:)
//             | {"latency_s": s, "per_byte_s": s, "per_hop_s": s,
//                "service_s": s, "fault_s": s,  (fault_s optional)
//                "send_overhead_s": s,          (optional: the sender's CPU per message)
//                "poll_s": s,                   (optional: a node's CPU per look for mail)
//                "contention": true|false,      (optional, default false)
//                "seconds_per_ray": s}}         (optional: that machine's one-node
//                                                tracing speed; costs are then scaled
//                                                to this host's, as ipsc2 is)
//
// Every key is optional; an unknown key, a wrong type or a bad value is an
// error naming the file and the key.
#pragma once

#include <optional>
#include <string>

#include "core/cost_model.h"

namespace raynode::apps {

/// A network described by its figures (nodes::NetworkModel's, before scaling).
struct NetworkFigures {
  double latency_s = 0, per_byte_s = 0, per_hop_s = 0, service_s = 0, send_overhead_s = 0, poll_s = 0;
  double fault_s = -1;          ///< < 0: the cost model's
  double cache_access_s = -1;   ///< nodes::NetworkModel::cache_access_s; < 0: the cost model's
  bool contention = false;      ///< links held while a message streams (nodes/links.h)
  double seconds_per_ray = 0;   ///< > 0: scale every cost by (this host's seconds per ray) / this
};

/// What a machine description sets; unset fields keep the command's defaults.
struct MachineDescription {
  std::string name;
  std::optional<std::string> node_memory, topology, clock;
  std::optional<std::uint32_t> page_size;
  std::optional<double> corun_slowdown;       ///< nodes::MachineParams::corun_slowdown
  std::optional<core::CostModel> cost_model;  ///< nodes::MachineParams::cost_model
  std::optional<std::string> network;          ///< a preset name
  std::optional<NetworkFigures> network_figures;  ///< or its figures
};

/// The built-in machine `name` ("ipsc2"), else the JSON file at `name`.
/// Throws UsageError (exit 2) naming the file, the key and the problem.
MachineDescription load_machine(const std::string& name);

}  // namespace raynode::apps
