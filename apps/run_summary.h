// The human-readable summary of a node-mode render (`raynode render`
// without --quiet): the machine, the work farm, svm's paging and dataflow's
// ray traffic, a line each, read from the same JSON objects that --stats
// writes (so the two can never disagree). Pure formatting: no machine.
#pragma once

#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

namespace raynode::apps {

/// The summary lines of a node-mode run, from --stats' objects:
/// `machine` (its "machine" object: count, topology, network, clock,
/// parallel_time_s, efficiency_estimate, total.messages_sent/bytes_sent,
/// and for replicated and svm "work" and "submaps"), `svm` (its "svm"
/// object, or null) and `dataflow` (its "dataflow" object, or null).
/// Returns no line when `machine` is null (an in-process mode). A key
/// that is missing is left out of its line, never guessed.
std::vector<std::string> node_run_summary(const nlohmann::json& machine, const nlohmann::json& svm,
                                          const nlohmann::json& dataflow);

}  // namespace raynode::apps
