// apps/node_runs.h: what a node-mode run reports of the balanced submaps'
// host estimate (NodeRun::estimate_s), which `bench nodes` charges in its
// eff_charged column, and charged_efficiency itself.
#include "apps/node_runs.h"

#include <doctest/doctest.h>

#include <limits>

#include "apps/commands.h"
#include "control/submap_plan.h"
#include "core/camera.h"
#include "core/scene_source.h"
#include "test_scenes.h"

using namespace raynode;

namespace {

apps::NodeRunSpec balanced_spec(nodes::ComputeClock clock) {
  apps::NodeRunSpec spec;
  spec.render.width = 40;
  spec.render.height = 32;
  spec.machine.node_memory = std::size_t(16) << 20;
  spec.machine.clock = clock;
  spec.submaps.rule = control::SubmapRule::kBalanced;
  spec.submaps.subsample = 4;
  return spec;
}

}  // namespace

TEST_CASE("node runs: balanced submaps report their host estimate in the clock's seconds, and one node traces none") {
  const testing::BuiltScene b = testing::build_spd("tetra", 3);
  const apps::NodeRunSpec spec = balanced_spec(nodes::ComputeClock::kModel);
  // The estimate the modes make: the scene's camera at the run's size.
  const core::Camera camera(core::render_view(b.db), 40, 32);
  const control::PixelCostEstimate direct =
      control::estimate_pixel_cost(b.db, b.grid, camera, spec.render, 4, spec.machine.cost_model);
  REQUIRE(direct.model_s > 0);
  for (const char* mode : {"svm", "replicated"}) {
    CAPTURE(mode);
    const apps::NodeRun two = apps::run_node_mode(b.db, b.grid, mode, spec, 2);
    REQUIRE(two.fits);
    REQUIRE(two.estimate_s.has_value());
    CHECK(*two.estimate_s == doctest::Approx(direct.model_s).epsilon(1e-12));  // modelled, so the same seconds
    const apps::NodeRun one = apps::run_node_mode(b.db, b.grid, mode, spec, 1);
    REQUIRE(one.fits);
    REQUIRE(one.estimate_s.has_value());
    CHECK(*one.estimate_s == 0.0);  // one submap, the whole image: nothing to estimate
    // Charged, the two-node run's efficiency falls below the uncharged one.
    const double plain = apps::charged_efficiency(one.parallel_time_s, two.parallel_time_s, 2, 0);
    CHECK(apps::charged_efficiency(one.parallel_time_s, two.parallel_time_s, 2, *two.estimate_s) < plain);
  }
  // Under the CPU clock the estimate's host wall seconds.
  const apps::NodeRun cpu = apps::run_node_mode(b.db, b.grid, "svm", balanced_spec(nodes::ComputeClock::kCpu), 2);
  REQUIRE(cpu.estimate_s.has_value());
  CHECK(*cpu.estimate_s > 0);
  // Square submaps and dataflow have no estimate of submaps to report.
  apps::NodeRunSpec square = spec;
  square.submaps.rule = control::SubmapRule::kSquare;
  CHECK_FALSE(apps::run_node_mode(b.db, b.grid, "svm", square, 2).estimate_s.has_value());
  CHECK_FALSE(apps::run_node_mode(b.db, b.grid, "dataflow", spec, 2).estimate_s.has_value());
}

TEST_CASE("node runs: charged_efficiency") {
  CHECK(apps::charged_efficiency(8.0, 1.0, 8, 0.0) == 1.0);     // the paper's T_1 / (n T_p)
  CHECK(apps::charged_efficiency(8.0, 1.0, 8, 1.0) == 0.5);     // a serial step as long as T_p halves it
  CHECK(apps::charged_efficiency(6.0, 1.0, 4, 0.5) == 1.0);     // 6 / (4 x 1.5)
  CHECK(apps::charged_efficiency(0.0, 1.0, 8, 0.0) == 0.0);     // no T_1
  CHECK(apps::charged_efficiency(8.0, 0.0, 8, 0.0) == 0.0);     // no T_p
}

TEST_CASE("node runs: hours_minutes_seconds writes Table 3's times") {
  CHECK(apps::hours_minutes_seconds(11522.0) == "3:12:02");  // Teapot on one iPSC/2 node
  CHECK(apps::hours_minutes_seconds(200.4) == "0:03:20");
  CHECK(apps::hours_minutes_seconds(59.5) == "0:01:00");     // rounded to the second
  CHECK(apps::hours_minutes_seconds(0.0) == "0:00:00");
  CHECK(apps::hours_minutes_seconds(-1.0) == "?");
  CHECK(apps::hours_minutes_seconds(std::numeric_limits<double>::infinity()) == "?");
}

TEST_CASE("node runs: calibrate_model_clock measures the model clock on the scene, and scales it as asked") {
  const testing::BuiltScene b = testing::build_spd("balls", 1);
  core::RenderParams rp;
  nodes::MachineParams m;
  m.clock = nodes::ComputeClock::kModel;
  const core::CostModel before = m.cost_model;
  // off: nothing measured, nothing changed.
  CHECK_FALSE(apps::calibrate_model_clock(m, rp, b.db, b.grid, "off").measured);
  CHECK(m.cost_model.unit_s == before.unit_s);
  CHECK(apps::ModelCalibration{}.to_json().is_null());
  // on: measured against Teapot, every unit cost scaled by the same ratio.
  const apps::ModelCalibration on = apps::calibrate_model_clock(m, rp, b.db, b.grid, "on");
  REQUIRE(on.measured);
  CHECK(on.applied);
  CHECK(on.cpu_s > 0);
  CHECK(on.model_s > 0);
  CHECK(on.reference_cpu_s > 0);
  CHECK(on.ratio == doctest::Approx((on.cpu_s / on.model_s) / (on.reference_cpu_s / on.reference_model_s)));
  for (std::size_t i = 0; i < before.unit_s.size(); ++i)
    CHECK(m.cost_model.unit_s[i] == doctest::Approx(before.unit_s[i] * on.ratio));
  const nlohmann::json j = on.to_json();
  CHECK(j["applied"] == true);
  CHECK(j["error"].get<double>() == doctest::Approx(on.ratio - 1));
  CHECK(j["reference"]["scene"] == "teapot:8");
  // auto applies only beyond the threshold.
  nodes::MachineParams a;
  a.clock = nodes::ComputeClock::kModel;
  const apps::ModelCalibration automatic = apps::calibrate_model_clock(a, rp, b.db, b.grid, "auto");
  REQUIRE(automatic.measured);
  CHECK(automatic.applied == (std::abs(automatic.ratio - 1) > apps::kCalibrateAbove));
  CHECK_FALSE(on.same_work);
  // The reference scene itself, loaded as the commands load it: its own
  // work, ratio exactly 1, not timed against itself (a ratio there would be
  // the host's noise alone).
  testing::BuiltScene teapot;
  teapot.db = core::make_database(core::load_scene(apps::tracing_source("teapot:8")));
  teapot.grid = core::build_grid(teapot.db);
  nodes::MachineParams t;
  t.clock = nodes::ComputeClock::kModel;
  const apps::ModelCalibration self = apps::calibrate_model_clock(t, rp, teapot.db, teapot.grid, "auto");
  REQUIRE(self.measured);
  CHECK(self.same_work);
  CHECK(self.ratio == 1.0);
  CHECK_FALSE(self.applied);
  CHECK(self.model_s == self.reference_model_s);
  CHECK(t.cost_model.unit_s == before.unit_s);
  CHECK(self.to_json()["same_work"] == true);
  // The CPU clock needs none.
  nodes::MachineParams cpu;
  cpu.clock = nodes::ComputeClock::kCpu;
  CHECK_FALSE(apps::calibrate_model_clock(cpu, rp, b.db, b.grid, "on").measured);
}
