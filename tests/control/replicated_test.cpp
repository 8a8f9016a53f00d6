#include <doctest/doctest.h>

#include <algorithm>
#include <cstring>
#include <nlohmann/json.hpp>
#include <string>

#include "core/database.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/spd.h"
#include "control/replicated.h"
#include "control/submap_plan.h"
#include "test_scenes.h"

using namespace raynode;
using namespace raynode::nodes;
using namespace raynode::control;

namespace {
/// n nodes of 8 MiB rendering `rp`, with a watchdog (a hang fails the test).
ReplicatedParams params(const core::RenderParams& rp, std::uint32_t n) {
  ReplicatedParams p;
  p.render = rp;
  p.machine.nodes = n;
  p.machine.node_memory = 8 * kMiB;
  p.machine.timeout_s = 120;
  return p;
}
}  // namespace

TEST_CASE("replicated: images and AOVs are bit-identical to sequential for N in {1, 2, 3, 7, 16, 64}") {
  for (auto [name, size] : {std::pair{"balls", 1}, std::pair{"rings", 1}}) {
    const testing::BuiltScene b = testing::build_spd(name, size);
    core::RenderParams rp;
    rp.width = 40;
    rp.height = 30;
    rp.depth_aov = rp.normal_aov = rp.primitive_aov = true;
    const core::RenderResult seq = core::render(b.db, b.grid, rp);
    for (std::uint32_t n : {1u, 2u, 3u, 7u, 16u, 64u}) {
      CAPTURE(name);
      CAPTURE(n);
      ReplicatedParams p = params(rp, n);
      p.node_aov = true;
      const ReplicatedResult r = render_replicated(b.db, b.grid, p);
      CHECK(testing::same_bytes(r.render.color, seq.color));
      CHECK(testing::same_bytes(r.render.depth, seq.depth));
      CHECK(testing::same_bytes(r.render.normal, seq.normal));
      CHECK(testing::same_bytes(r.render.primitive, seq.primitive));
      CHECK(r.render.stats.rays.total() == seq.stats.rays.total());
      CHECK(r.render.stats.traversal.triangle_tests + r.render.stats.traversal.sphere_tests ==
            seq.stats.traversal.triangle_tests + seq.stats.traversal.sphere_tests);
      std::uint64_t pixels = 0;
      for (const WorkStats& w : r.work) pixels += w.pixels;
      CHECK(pixels == 40u * 30u);
      // Every pixel's node id is a real node, and with several nodes more than one worked.
      float lo = 1e9f, hi = -1;
      for (float v : r.node.pixels) lo = std::min(lo, v), hi = std::max(hi, v);
      CHECK(lo >= 0);
      CHECK(hi <= float(n - 1));
      if (n > 1) CHECK(hi > lo);
      CHECK(r.run.total().sent[std::size_t(MessageType::kPixels)].messages > 0);
      CHECK(r.run.nodes.front().memory_peak >= r.database_bytes);  // the copy really sits in the arena
    }
  }
}

TEST_CASE("replicated: a database that does not fit a node fails at once with both sizes") {
  const testing::BuiltScene b = testing::build_spd("tetra", 4);  // 1024 triangles
  ReplicatedParams p;
  p.render.width = p.render.height = 8;
  p.machine.nodes = 4;
  p.machine.node_memory = 32 * 1024;
  try {
    render_replicated(b.db, b.grid, p);
    FAIL("must throw");
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    CHECK(what.find("replicated mode: the database needs") == 0);
    CHECK(what.find(std::to_string(replicated_bytes_per_node(b.db, b.grid)) + " B") != std::string::npos);
    CHECK(what.find("--node-memory is 32 KiB") != std::string::npos);
  }
}

TEST_CASE("replicated: 256 nodes on this machine terminate cleanly with the sequential image") {
  const testing::BuiltScene b = testing::build_spd("balls", 1);
  core::RenderParams rp;
  rp.width = 48;
  rp.height = 40;
  const core::RenderResult seq = core::render(b.db, b.grid, rp);
  ReplicatedParams p;
  p.render = rp;
  p.machine.nodes = 256;
  p.machine.timeout_s = 120;  // a hang fails the test instead of blocking CI
  const ReplicatedResult r = render_replicated(b.db, b.grid, p);
  CHECK(testing::same_bytes(r.render.color, seq.color));
  CHECK(r.run.nodes.size() == 256);
  CHECK(r.run.total().received[std::size_t(MessageType::kShutdown)].messages == 256);
}

TEST_CASE("replicated: under the model clock a node's busy time is exactly the modelled cost of its rays") {
  const testing::BuiltScene b = testing::build_spd("balls", 1);
  core::RenderParams rp;
  rp.width = 48;
  rp.height = 32;
  for (std::uint32_t n : {1u, 4u}) {
    CAPTURE(n);
    ReplicatedParams p = params(rp, n);
    p.machine.clock = ComputeClock::kModel;  // network none: no service charges either
    const ReplicatedResult r1 = render_replicated(b.db, b.grid, p);
    double busy = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const double node_model = p.machine.cost_model.seconds(r1.tracing[i].rays, r1.tracing[i].traversal);
      CHECK(r1.run.nodes[i].counters.busy_s == doctest::Approx(node_model).epsilon(1e-9));
      busy += r1.run.nodes[i].counters.busy_s;
    }
    const double total_model = p.machine.cost_model.seconds(r1.render.stats.rays, r1.render.stats.traversal);
    CHECK(busy == doctest::Approx(total_model).epsilon(1e-9));
    CHECK(r1.run.parallel_time_s >= total_model / n * (1 - 1e-9));
    if (n == 1) {  // one node: T_1 is the modelled cost, the same in every run
      CHECK(r1.run.parallel_time_s == doctest::Approx(total_model).epsilon(1e-9));
      const ReplicatedResult r2 = render_replicated(b.db, b.grid, p);
      CHECK(r2.run.parallel_time_s == r1.run.parallel_time_s);
    }
  }
}

TEST_CASE("replicated: a co-running slowdown and a look for mail's time are charged on more than one node only") {
  const testing::BuiltScene b = testing::build_spd("balls", 1);
  core::RenderParams rp;
  rp.width = 48;
  rp.height = 32;
  const double look = 2e-6;
  for (std::uint32_t n : {1u, 3u}) {
    CAPTURE(n);
    ReplicatedParams p = params(rp, n);
    p.machine.clock = ComputeClock::kModel;
    p.machine.corun_slowdown = 1.5;
    p.machine.network.poll_s = look;
    const ReplicatedResult r = render_replicated(b.db, b.grid, p);
    const double factor = n > 1 ? 1.5 : 1.0, per_look = n > 1 ? look : 0.0;
    CHECK(r.run.corun_slowdown == factor);
    for (std::size_t i = 0; i < n; ++i) {
      const double node_model = p.machine.cost_model.seconds(r.tracing[i].rays, r.tracing[i].traversal);
      const nodes::NodeCounters& c = r.run.nodes[i].counters;
      CHECK(c.mail_checks > 0);
      CHECK(c.busy_s == doctest::Approx(factor * node_model + double(c.mail_checks) * per_look).epsilon(1e-9));
    }
    CHECK(testing::same_bytes(r.render.color, core::render(b.db, b.grid, rp).color));
  }
  // The CPU clock measures the threads themselves: no factor.
  ReplicatedParams p = params(rp, 2);
  p.machine.corun_slowdown = 1.5;
  CHECK(render_replicated(b.db, b.grid, p).run.corun_slowdown == 1.0);
  p.machine.corun_slowdown = 0.5;
  CHECK_THROWS_AS(render_replicated(b.db, b.grid, p), std::invalid_argument);
}

TEST_CASE("submap plan: the host's estimate charges each block its traced pixel's modelled cost") {
  const testing::BuiltScene b = testing::build_spd("teapot", 2);
  core::RenderParams rp;
  rp.width = 36;
  rp.height = 20;
  const core::Camera camera(core::render_view(b.db), rp.width, rp.height);
  const core::CostModel model = core::default_cost_model();
  // Every pixel traced once: the estimate's cost is the sequential render's modelled cost.
  const core::RenderResult seq = core::render(b.db, b.grid, rp);
  const PixelCostEstimate all = estimate_pixel_cost(b.db, b.grid, camera, rp, 1, model);
  CHECK(all.pixels == 36u * 20u);
  CHECK(all.rays == seq.stats.rays.total());
  CHECK(all.model_s == doctest::Approx(model.seconds(seq.stats.rays, seq.stats.traversal)).epsilon(1e-9));
  double sum = 0;
  for (double c : all.cost) sum += c;
  CHECK(sum == doctest::Approx(all.model_s).epsilon(1e-9));
  // One pixel per 8x8 block (the last blocks clipped to the image): each
  // block costs its traced pixel, the one at the block's centre.
  const PixelCostEstimate est = estimate_pixel_cost(b.db, b.grid, camera, rp, 8, model);
  CHECK(est.pixels == 5u * 3u);
  double blocks = 0;
  for (int by = 0; by < 20; by += 8)
    for (int bx = 0; bx < 36; bx += 8) {
      const int x1 = std::min(bx + 8, 36), y1 = std::min(by + 8, 20);
      const double c = est.cost[std::size_t(by) * 36 + bx];
      CHECK(c == all.cost[std::size_t((by + y1) / 2) * 36 + (bx + x1) / 2]);
      for (int y = by; y < y1; ++y)
        for (int x = bx; x < x1; ++x) CHECK(est.cost[std::size_t(y) * 36 + x] == c);
      blocks += c;
    }
  CHECK(est.model_s == doctest::Approx(blocks).epsilon(1e-12));
  // The teapot's pixels cost more than the background's.
  const auto [lo, hi] = std::minmax_element(all.cost.begin(), all.cost.end());
  CHECK(*hi > 3 * *lo);
  CHECK_THROWS_AS(estimate_pixel_cost(b.db, b.grid, camera, rp, 0, model), std::invalid_argument);
}

TEST_CASE("replicated: balanced submaps keep the sequential image, and the plan reports its estimate") {
  const testing::BuiltScene b = testing::build_spd("tetra", 3);
  core::RenderParams rp;
  rp.width = 40;
  rp.height = 32;
  const core::RenderResult seq = core::render(b.db, b.grid, rp);
  for (std::uint32_t n : {3u, 16u}) {
    CAPTURE(n);
    ReplicatedParams p = params(rp, n);
    p.submaps.rule = SubmapRule::kBalanced;
    p.submaps.subsample = 4;
    const ReplicatedResult r = render_replicated(b.db, b.grid, p);
    CHECK(testing::same_bytes(r.render.color, seq.color));
    std::uint64_t pixels = 0;
    for (const WorkStats& w : r.work) pixels += w.pixels;
    CHECK(pixels == 40u * 32u);
    REQUIRE(r.submaps.rects.size() == n);
    CHECK(r.submaps.rects != make_submaps(40, 32, n));  // the tetrahedron's pixels cost more than the sky's
    CHECK(r.submaps.estimate.pixels == 10u * 8u);
    CHECK(r.submaps.estimated_max_over_mean >= 1.0);
    CHECK(r.submaps.estimate.cost.empty());  // dropped once the cuts are made
    const nlohmann::json j = r.submaps.to_json();
    CHECK(j["rule"] == "balanced");
    CHECK(j["estimate"]["pixels"] == 80);
  }
}
