#include "apps/machine_file.h"

#include <fmt/core.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "apps/commands.h"
#include "nodes/machine.h"

namespace raynode::apps {

namespace {

MachineDescription ipsc2() {
  MachineDescription m;
  m.name = "ipsc2";
  m.node_memory = "4MiB";
  m.page_size = 1024;
  m.topology = "hypercube";
  m.clock = "model";
  m.network = "ipsc2";
  return m;
}

}  // namespace

MachineDescription load_machine(const std::string& name) {
  if (name == "ipsc2") return ipsc2();
  std::ifstream in(name, std::ios::binary);
  if (!in)
    throw UsageError(fmt::format("--machine: '{}' is neither a built-in machine (ipsc2) nor a readable file", name));
  std::ostringstream text;
  text << in.rdbuf();
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text.str());
  } catch (const nlohmann::json::exception& e) {
    throw UsageError(fmt::format("--machine {}: not valid JSON: {}", name, e.what()));
  }
  if (!j.is_object()) throw UsageError(fmt::format("--machine {}: expected a JSON object", name));
  auto bad = [&](const std::string& key, const std::string& why) {
    return UsageError(fmt::format("--machine {}: \"{}\" {}", name, key, why));
  };
  auto text_of = [&](const std::string& key, std::initializer_list<const char*> allowed) -> std::string {
    const nlohmann::json& v = j.at(key);
    if (!v.is_string()) throw bad(key, "must be a string");
    const std::string s = v.get<std::string>();
    if (allowed.size() == 0) return s;
    std::string names;
    for (const char* a : allowed) {
      if (s == a) return s;
      names += (names.empty() ? "" : ", ") + std::string(a);
    }
    throw bad(key, fmt::format("must be one of {}, got '{}'", names, s));
  };
  static const std::set<std::string> known{"name",  "about",          "node_memory", "page_size", "topology",
                                           "clock", "corun_slowdown", "cost_model",  "network"};
  for (const auto& [key, value] : j.items())
    if (!known.count(key))
      throw bad(key,
                "is not a machine key (name, about, node_memory, page_size, topology, clock, corun_slowdown, "
                "cost_model, network)");
  MachineDescription m;
  m.name = j.contains("name") ? text_of("name", {}) : name;
  if (j.contains("about")) text_of("about", {});
  if (j.contains("node_memory")) m.node_memory = text_of("node_memory", {});
  if (j.contains("topology")) m.topology = text_of("topology", {"hypercube", "ring", "torus"});
  if (j.contains("clock")) m.clock = text_of("clock", {"cpu", "model"});
  if (j.contains("corun_slowdown")) {
    const nlohmann::json& v = j.at("corun_slowdown");
    if (!v.is_number() || !(v.get<double>() >= 1 && v.get<double>() <= nodes::kMaxCorunSlowdown))
      throw bad("corun_slowdown", fmt::format("must be a number from 1 to {}", nodes::kMaxCorunSlowdown));
    m.corun_slowdown = v.get<double>();
  }
  if (j.contains("cost_model")) {
    const nlohmann::json& v = j.at("cost_model");
    if (!v.is_object()) throw bad("cost_model", "must be an object of unit costs by name");
    core::CostModel model = core::default_cost_model();
    for (const auto& [key, value] : v.items()) {
      int k = 0;
      while (k < core::kCostFeatureCount && key != core::cost_feature_name(core::CostFeature(k))) ++k;
      if (k == core::kCostFeatureCount) {
        std::string names;
        for (int i = 0; i < core::kCostFeatureCount; ++i)
          names += (i ? ", " : "") + std::string(core::cost_feature_name(core::CostFeature(i)));
        throw bad("cost_model." + key, "is not a unit cost (" + names + ")");
      }
      if (!value.is_number() || !std::isfinite(value.get<double>()) || value.get<double>() < 0)
        throw bad("cost_model." + key, "must be a finite number of seconds >= 0");
      model.unit_s[std::size_t(k)] = value.get<double>();
    }
    m.cost_model = model;
  }
  if (j.contains("page_size")) {
    const nlohmann::json& v = j.at("page_size");
    if (!v.is_number_unsigned() || v.get<std::uint64_t>() > 0xffffffffull)
      throw bad("page_size", "must be a whole number of bytes");
    m.page_size = std::uint32_t(v.get<std::uint64_t>());
  }
  if (j.contains("network")) {
    const nlohmann::json& v = j.at("network");
    if (v.is_string()) {
      m.network = text_of("network", {"none", "ipsc2", "cluster"});
    } else if (v.is_object()) {
      NetworkFigures f;
      static const std::set<std::string> figures{"latency_s",       "per_byte_s", "per_hop_s",
                                                 "service_s",       "fault_s",    "cache_access_s",
                                                 "send_overhead_s", "poll_s",     "seconds_per_ray"};
      for (const auto& [key, value] : v.items()) {
        if (key == "contention") {
          if (!value.is_boolean()) throw bad("network.contention", "must be true or false");
          f.contention = value.get<bool>();
          continue;
        }
        if (!figures.count(key))
          throw bad("network." + key, "is not a network figure (latency_s, per_byte_s, per_hop_s, service_s, "
                                      "fault_s, cache_access_s, send_overhead_s, poll_s, seconds_per_ray, "
                                      "contention)");
        if (!value.is_number() || !std::isfinite(value.get<double>()) || value.get<double>() < 0)
          throw bad("network." + key, "must be a finite number of seconds >= 0");
      }
      auto get = [&](const char* key, double fallback) { return v.contains(key) ? v.at(key).get<double>() : fallback; };
      f.latency_s = get("latency_s", 0);
      f.per_byte_s = get("per_byte_s", 0);
      f.per_hop_s = get("per_hop_s", 0);
      f.service_s = get("service_s", 0);
      f.fault_s = get("fault_s", -1);
      f.cache_access_s = get("cache_access_s", -1);
      f.send_overhead_s = get("send_overhead_s", 0);
      f.poll_s = get("poll_s", 0);
      f.seconds_per_ray = get("seconds_per_ray", 0);
      m.network_figures = f;
    } else {
      throw bad("network", "must be a preset name (none, ipsc2, cluster) or an object of figures");
    }
  }
  return m;
}

}  // namespace raynode::apps
