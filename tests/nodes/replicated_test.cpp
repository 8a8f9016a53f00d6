#include <doctest/doctest.h>

#include <cstring>
#include <string>

#include "core/database.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/spd.h"
#include "nodes/replicated.h"
#include "test_scenes.h"

using namespace raynode;
using namespace raynode::nodes;

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
      ReplicatedParams p;
      p.render = rp;
      p.machine.nodes = n;
      p.machine.node_memory = 8 * kMiB;
      p.machine.timeout_s = 120;
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
    ReplicatedParams p;
    p.render = rp;
    p.machine.nodes = n;
    p.machine.node_memory = 8 * kMiB;
    p.machine.timeout_s = 120;
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
