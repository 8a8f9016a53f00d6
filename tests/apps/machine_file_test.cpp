// apps/machine_file.h: a machine description's co-running slowdown and unit
// costs reach the machine a node-mode command builds, and a bad value is an
// error naming the file and the key.
#include "apps/machine_file.h"

#include <doctest/doctest.h>

#include <cstdio>
#include <fstream>
#include <string>

#include "apps/commands.h"
#include "apps/node_runs.h"
#include "core/cost_model.h"

using namespace raynode;

namespace {

/// Writes `text` to a fresh file and returns its path.
std::string description(const std::string& name, const std::string& text) {
  const std::string path = "machine_file_test_" + name + ".json";
  std::ofstream(path) << text;
  return path;
}

std::string error_of(const std::string& path) {
  try {
    (void)apps::load_machine(path);
  } catch (const apps::UsageError& e) {
    std::remove(path.c_str());
    return e.what();
  }
  std::remove(path.c_str());
  return "";
}

}  // namespace

TEST_CASE("machine file: cost_model sets the named unit costs and keeps the built-in model's others") {
  const std::string path =
      description("costs", R"({"clock": "model", "corun_slowdown": 1.25,
                               "cost_model": {"primary_ray": 1e-6, "lru_update": 0}})");
  const apps::MachineDescription m = apps::load_machine(path);
  std::remove(path.c_str());
  REQUIRE(m.cost_model);
  const core::CostModel built_in = core::default_cost_model();
  for (int k = 0; k < core::kCostFeatureCount; ++k) {
    const core::CostFeature f = core::CostFeature(k);
    CAPTURE(core::cost_feature_name(f));
    const double want = f == core::CostFeature::kPrimaryRay ? 1e-6
                        : f == core::CostFeature::kLruUpdate ? 0.0
                                                             : built_in.unit_s[std::size_t(k)];
    CHECK(m.cost_model->unit_s[std::size_t(k)] == want);
  }
  CHECK(m.corun_slowdown == 1.25);
  // Through the command's options into the machine it builds.
  apps::NodeRunOptions o;
  o.clock = *m.clock;
  o.network = "none";
  o.corun_slowdown = *m.corun_slowdown;
  o.cost_model = m.cost_model;
  const apps::NodeRunSpec spec = apps::make_node_run_spec(o);
  CHECK(spec.machine.cost_model.unit_s == m.cost_model->unit_s);
  CHECK(spec.machine.corun_slowdown == 1.25);
}

TEST_CASE("machine file: a bad unit cost or slowdown names the file and the key") {
  CHECK(error_of(description("name", R"({"cost_model": {"primary_rays": 1e-8}})"))
            .find("\"cost_model.primary_rays\" is not a unit cost (primary_ray") != std::string::npos);
  CHECK(error_of(description("negative", R"({"cost_model": {"cell": -1}})"))
            .find("\"cost_model.cell\" must be a finite number of seconds >= 0") != std::string::npos);
  CHECK(error_of(description("array", R"({"cost_model": [1, 2]})"))
            .find("\"cost_model\" must be an object of unit costs by name") != std::string::npos);
  CHECK(error_of(description("slow", R"({"corun_slowdown": 0.5})"))
            .find("\"corun_slowdown\" must be a number from 1 to 100") != std::string::npos);
  CHECK(error_of(description("poll", R"({"network": {"poll_s": -1e-6}})"))
            .find("\"network.poll_s\" must be a finite number of seconds >= 0") != std::string::npos);
}

TEST_CASE("machine file: a network's cache_access_s reaches the machine, scaled as the other figures") {
  const std::string path = description(
      "cache_access", R"({"clock": "model", "network": {"latency_s": 1e-3, "cache_access_s": 2e-5,
                                                        "seconds_per_ray": 1e-2}})");
  const apps::MachineDescription m = apps::load_machine(path);
  std::remove(path.c_str());
  REQUIRE(m.network_figures);
  CHECK(m.network_figures->cache_access_s == 2e-5);
  apps::NodeRunOptions o;
  o.clock = *m.clock;
  o.machine = "cache_access";
  o.network = "custom";
  o.network_figures = m.network_figures;
  o.network_scale = 1e-6;  // this host's seconds per ray: every figure x 1e-4
  const apps::NodeRunSpec spec = apps::make_node_run_spec(o);
  CHECK(spec.machine.network.cache_access_s == doctest::Approx(2e-9));
  CHECK(spec.machine.network.latency_s == doctest::Approx(1e-7));
  // Left out, the figure stays unset (the cost model's), not 0 scaled.
  const std::string unset_path =
      description("cache_unset", R"({"clock": "model", "network": {"latency_s": 1e-3, "seconds_per_ray": 1e-2}})");
  const apps::MachineDescription unset = apps::load_machine(unset_path);
  std::remove(unset_path.c_str());
  REQUIRE(unset.network_figures);
  CHECK(unset.network_figures->cache_access_s < 0);
  o.network_figures = unset.network_figures;
  CHECK(apps::make_node_run_spec(o).machine.network.cache_access_s < 0);
  CHECK(error_of(description("cache_negative", R"({"network": {"cache_access_s": -1}})"))
            .find("\"network.cache_access_s\" must be a finite number of seconds >= 0") != std::string::npos);
}
