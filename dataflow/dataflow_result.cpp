#include <algorithm>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "dataflow/dataflow.h"

namespace raynode::dataflow {

const char* ray_kind_name(RayKind kind) {
  switch (kind) {
    case RayKind::kPrimary: return "primary";
    case RayKind::kShadow: return "shadow";
    case RayKind::kReflected: return "reflected";
    case RayKind::kRefracted: return "refracted";
  }
  return "?";
}

PartitionKind parse_partition(const std::string& name) {
  if (name == "balanced") return PartitionKind::kBalanced;
  if (name == "equal") return PartitionKind::kEqual;
  throw std::invalid_argument("unknown partition '" + name + "' (expected balanced or equal)");
}

const char* partition_name(PartitionKind kind) { return kind == PartitionKind::kEqual ? "equal" : "balanced"; }

std::uint64_t DataflowResult::ray_messages() const {
  std::uint64_t t = 0;
  for (const NodeFlowStats& s : per_node)
    for (int k = 0; k < kRayKindCount; ++k) t += s.rays_sent[k].messages + s.rays_spilled[k].messages;
  return t;
}

double DataflowResult::spill_fraction() const {
  const std::uint64_t all = ray_messages();
  return all ? double(host.spilled) / double(all) : 0.0;
}

std::vector<double> DataflowResult::measured_load() const {
  std::vector<double> load;
  for (const nodes::NodeReport& r : run.nodes)
    load.push_back(run.parallel_time_s > 0 ? r.counters.busy_s / run.parallel_time_s : 0.0);
  return load;
}

double DataflowResult::average_load() const {
  const std::vector<double> l = measured_load();
  double s = 0;
  for (double v : l) s += v;
  return l.empty() ? 0.0 : s / double(l.size());
}

nlohmann::json DataflowResult::to_json() const {
  nlohmann::json j;
  j["partition"] = partition_name(partition);
  j["regions"] = regions.size();
  j["estimate"] = {{"pixels", estimate.pixels},
                   {"rays", estimate.rays},
                   {"host_s", estimate.seconds},
                   {"cost_grid", {estimate.cost.nx, estimate.cost.ny}},
                   {"cost_extent", {estimate.cost.extent.x0, estimate.cost.extent.y0, estimate.cost.extent.x1,
                                    estimate.cost.extent.y1}},
                   {"refined", estimate.refined},
                   {"total_cost", estimate.cost.total()}};
  j["setup_s"] = setup_s;
  nlohmann::json by_kind = nlohmann::json::object();
  std::uint64_t shared_tests = 0, contributions = 0, contribution_messages = 0, segments = 0;
  for (int k = 0; k < kRayKindCount; ++k) {
    std::uint64_t msgs = 0, bytes = 0, spilled = 0, received = 0;
    for (const NodeFlowStats& s : per_node) {
      msgs += s.rays_sent[k].messages;
      bytes += s.rays_sent[k].bytes + s.rays_spilled[k].bytes;
      spilled += s.rays_spilled[k].messages;
      received += s.rays_received[k];
    }
    by_kind[ray_kind_name(RayKind(k))] = {
        {"messages", msgs + spilled}, {"bytes", bytes}, {"spilled", spilled}, {"received", received}};
  }
  for (const NodeFlowStats& s : per_node) {
    shared_tests += s.shared_tests;
    contributions += s.contributions;
    contribution_messages += s.contribution_messages;
    segments += s.segments;
  }
  j["ray_messages"] = by_kind;
  j["ray_messages_total"] = ray_messages();
  j["ray_segments"] = segments;
  j["contributions"] = contributions;
  j["contribution_messages"] = contribution_messages;
  j["host"] = {{"spilled", host.spilled},           {"forwarded", host.forwarded},
               {"forward_retries", host.forward_retries}, {"store_peak", host.store_peak},
               {"contributions", host.contributions},    {"first_hits", host.first_hits},
               {"termination_waves", host.waves}};
  j["spill_fraction"] = spill_fraction();
  std::uint64_t queued = 0, queue_peak = 0;
  for (const NodeFlowStats& s : per_node) queued += s.rays_queued, queue_peak = std::max(queue_peak, s.send_queue_peak);
  j["send_queue"] = {{"rays_queued", queued}, {"peak", queue_peak}};
  std::size_t held = 0, shared_prims = 0;
  for (const RegionReport& r : regions) held += r.primitives, shared_prims += r.shared_primitives;
  j["primitives_held"] = held;
  j["shared_primitive_copies"] = shared_prims;
  j["shared_primitive_tests"] = shared_tests;
  const std::vector<double> load = measured_load();
  double est_total = 0, busy_total = 0;
  for (const RegionReport& r : regions) est_total += r.estimated_cost;
  for (const nodes::NodeReport& r : run.nodes) busy_total += r.counters.busy_s;
  nlohmann::json per = nlohmann::json::array();
  for (std::size_t i = 0; i < regions.size(); ++i) {
    const RegionReport& r = regions[i];
    const double busy = i < run.nodes.size() ? run.nodes[i].counters.busy_s : 0.0;
    // rect: screen frame, within the extent; grid_resolution: an adaptive grid's top grid.
    nlohmann::json region = {{"region", i},
                             {"node", r.node},
                             {"rect", {r.finite.x0, r.finite.y0, r.finite.x1, r.finite.y1}},
                             {"primitives", r.primitives},
                             {"shared_primitives", r.shared_primitives},
                             {"grid_kind", core::grid_kind_name(r.grid_kind)},
                             {"grid_resolution", {r.grid_res[0], r.grid_res[1], r.grid_res[2]}},
                             {"grid_references", r.grid_references},
                             {"grid_bytes", r.grid_bytes},
                             {"bytes", r.bytes},
                             {"estimated_share", est_total > 0 ? r.estimated_cost / est_total : 0.0},
                             {"measured_share", busy_total > 0 ? busy / busy_total : 0.0},
                             {"busy_s", busy},
                             {"load", i < load.size() ? load[i] : 0.0},
                             {"primaries", i < per_node.size() ? per_node[i].primaries : 0},
                             {"segments", i < per_node.size() ? per_node[i].segments : 0}};
    if (r.grid_kind == core::GridKind::kAdaptive) {
      region["grid_sub_grids"] = r.grid_sub_grids;
      region["grid_leaf_cells"] = r.grid_leaf_cells;
    }
    per.push_back(std::move(region));
  }
  double max_busy = 0;
  for (const nodes::NodeReport& r : run.nodes) max_busy = std::max(max_busy, r.counters.busy_s);
  j["average_load"] = average_load();
  j["balance"] = max_busy > 0 && !run.nodes.empty() ? busy_total / double(run.nodes.size()) / max_busy : 0.0;
  j["per_region"] = std::move(per);
  return j;
}

}  // namespace raynode::dataflow
