#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <string>

#include "core/database.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/scene.h"
#include "core/spd.h"
#include "dataflow/dataflow.h"
#include "test_scenes.h"

using namespace raynode;
using namespace raynode::dataflow;

namespace {

/// Largest per-channel difference; +inf on a shape mismatch.
float max_diff(const core::Image& a, const core::Image& b) {
  if (a.width != b.width || a.height != b.height || a.channels != b.channels) return core::kInfinity;
  float m = 0;
  for (std::size_t i = 0; i < a.pixels.size(); ++i) {
    const float x = a.pixels[i], y = b.pixels[i];
    if (x == y) continue;  // also equal infinities
    m = std::max(m, std::fabs(x - y));
  }
  return m;
}

DataflowParams params_for(const core::RenderParams& rp, std::uint32_t nodes) {
  DataflowParams p;
  p.render = rp;
  p.machine.nodes = nodes;
  p.machine.node_memory = 16 * nodes::kMiB;
  p.machine.timeout_s = 120;
  return p;
}

core::GridParams grid_params(core::GridKind kind, float sub_grid_min = 128) {
  core::GridParams g;
  g.kind = kind;
  g.sub_grid_min = sub_grid_min;
  return g;
}

/// The SPD teapot (size `size`) with one more polygon: a square floor just
/// below it, `scale` times the model's width (a dense mesh on a huge floor,
/// where an adaptive grid refines the mesh's cells).
core::Database teapot_on_floor(int size, float scale) {
  core::Scene s = core::make_spd_scene(core::SpdParams{"teapot", size, 0});
  const core::Bounds3 b = core::make_database(s).bounds;
  const core::Vec3 c = b.center();
  const float half = 0.5f * scale * std::max(b.upper.x - b.lower.x, b.upper.y - b.lower.y);
  const float z = b.lower.z - 0.01f * (b.upper.z - b.lower.z);
  const core::Vec3 quad[4] = {
      {c.x - half, c.y - half, z}, {c.x + half, c.y - half, z}, {c.x + half, c.y + half, z}, {c.x - half, c.y + half, z}};
  s.add_polygon(quad, 4);
  return core::make_database(s);
}

void check_counters_match(const core::RenderStats& a, const core::RenderStats& b) {
  CHECK(a.rays.primary == b.rays.primary);
  CHECK(a.rays.shadow == b.rays.shadow);
  CHECK(a.rays.reflected == b.rays.reflected);
  CHECK(a.rays.refracted == b.rays.refracted);
  CHECK(a.skipped.shadow_backfacing == b.skipped.shadow_backfacing);
  CHECK(a.skipped.highlight_marker == b.skipped.highlight_marker);
  CHECK(a.skipped.depth_limit == b.skipped.depth_limit);
}

}  // namespace

TEST_CASE("dataflow: images equal sequential within 1e-5 for N in {1, 2, 3, 4, 8, 12, 32, 64}, both grid kinds") {
  struct Case {
    const char* name;
    int size;
    int tessellate;
  };
  for (const Case& sc : {Case{"rings", 1, 0}, Case{"balls", 1, 0}, Case{"teapot", 2, 0}, Case{"mount", 2, 0},
                         Case{"tetra", 3, 0}, Case{"rings", 1, 1}})
    for (const core::GridKind kind : {core::GridKind::kUniform, core::GridKind::kAdaptive}) {
      testing::BuiltScene b = testing::build_spd(sc.name, sc.size, sc.tessellate);
      b.grid = core::build_grid(b.db, grid_params(kind));  // the host's grid, as the CLI builds it
      core::RenderParams rp;
      rp.width = 48;
      rp.height = 32;
      const core::RenderResult seq = core::render(b.db, b.grid, rp);
      for (std::uint32_t n : {1u, 2u, 3u, 4u, 8u, 12u, 32u, 64u}) {
        CAPTURE(sc.name);
        const char* grid = core::grid_kind_name(kind);
        CAPTURE(grid);
        CAPTURE(n);
        DataflowParams p = params_for(rp, n);
        p.grid.kind = kind;
        const DataflowResult r = render_dataflow(b.db, b.grid, p);
        CHECK(max_diff(r.render.color, seq.color) <= 1e-5f);
        check_counters_match(r.render.stats, seq.stats);
        CHECK(r.regions.size() == n);
        for (const RegionReport& g : r.regions) CHECK(g.grid_kind == kind);
        CHECK(r.host.contributions == [&] {
          std::uint64_t c = 0;
          for (const NodeFlowStats& s : r.per_node) c += s.contributions;
          return c;
        }());
        if (n > 1 && std::string(sc.name) != "tetra") CHECK(r.ray_messages() > 0);
      }
    }
}

TEST_CASE("dataflow: a mesh on a huge floor renders as sequential with adaptive local grids, the floor beside them or in them") {
  for (const bool beside_top : {true, false}) {
  CAPTURE(beside_top);
  // Sub-grids from 8 primitives on, so that a small scene's regions get
  // them (the floor in the top grids: beside the sub-grids over the mesh).
  core::GridParams adaptive = grid_params(core::GridKind::kAdaptive, 8);
  adaptive.large_beside_top = beside_top;
  const core::Database db = teapot_on_floor(3, 200.0f);
  const core::Grid host = core::build_grid(db, adaptive);
  CHECK(host.sub_grids.at(0).large_list == beside_top);
  if (!beside_top) REQUIRE(host.sub_grid_count() > 0);
  core::RenderParams rp;
  rp.width = 48;
  rp.height = 40;
  rp.depth_aov = rp.primitive_aov = true;
  const core::RenderResult seq = core::render(db, host, rp);
  std::size_t hit_pixels = 0;
  for (float v : seq.primitive.pixels) hit_pixels += v >= 0;
  REQUIRE(hit_pixels > 0);
  for (std::uint32_t n : {1u, 4u, 9u}) {
    CAPTURE(n);
    DataflowParams p = params_for(rp, n);
    p.grid = adaptive;
    const DataflowResult r = render_dataflow(db, host, p);
    CHECK(max_diff(r.render.color, seq.color) <= 1e-5f);
    // The same primitive and distance at every pixel: the walk enters the regions' sub-grids.
    CHECK(max_diff(r.render.primitive, seq.primitive) == 0.0f);
    CHECK(max_diff(r.render.depth, seq.depth) == 0.0f);
    check_counters_match(r.render.stats, seq.stats);
    std::size_t refined = 0;
    for (const RegionReport& g : r.regions) {
      CHECK(g.grid_kind == core::GridKind::kAdaptive);
      CHECK(g.grid_leaf_cells >= std::size_t(g.grid_res[0]) * g.grid_res[1] * g.grid_res[2]);
      CHECK(g.bytes > g.grid_bytes);
      refined += g.grid_sub_grids > 0;
    }
    if (!beside_top) CHECK(refined > 0);
    // The stats name each region's grid kind and, adaptive, its sub-grids and leaf cells.
    const nlohmann::json j = r.to_json();
    for (const nlohmann::json& g : j["per_region"]) {
      CHECK(g["grid_kind"] == "adaptive");
      CHECK(g.contains("grid_sub_grids"));
      CHECK(g["grid_leaf_cells"].get<std::size_t>() > 0);
    }
    // The paper's uniform local grids give the same image over the same host grid.
    p.grid = grid_params(core::GridKind::kUniform);
    const DataflowResult u = render_dataflow(db, host, p);
    CHECK(max_diff(u.render.color, seq.color) <= 1e-5f);
    CHECK(max_diff(u.render.primitive, seq.primitive) == 0.0f);
    for (const RegionReport& g : u.regions) CHECK(g.grid_sub_grids == 0);
    CHECK_FALSE(u.to_json()["per_region"][0].contains("grid_sub_grids"));
    CHECK(u.to_json()["per_region"][0]["grid_kind"] == "uniform");
  }
  }
}

TEST_CASE("dataflow: AOVs equal sequential and the region AOV names the region of each primary hit") {
  const testing::BuiltScene b = testing::build_spd("rings", 1);
  core::RenderParams rp;
  rp.width = 40;
  rp.height = 30;
  rp.depth_aov = rp.normal_aov = rp.primitive_aov = true;
  const core::RenderResult seq = core::render(b.db, b.grid, rp);
  for (int spp : {1, 2}) {
    CAPTURE(spp);
    rp.spp = spp;
    const core::RenderResult s = core::render(b.db, b.grid, rp);
    DataflowParams p = params_for(rp, 7);
    p.region_aov = true;
    const DataflowResult r = render_dataflow(b.db, b.grid, p);
    CHECK(max_diff(r.render.color, s.color) <= 1e-5f);
    CHECK(max_diff(r.render.depth, s.depth) == 0.0f);
    CHECK(max_diff(r.render.normal, s.normal) == 0.0f);
    CHECK(max_diff(r.render.primitive, s.primitive) == 0.0f);
    CHECK(r.render.stats.rays.primary == s.stats.rays.primary);
    // Region ids: -1 exactly where the eye ray misses, else a region; several regions appear.
    REQUIRE(r.region.width == 40);
    float lo = 1e9f, hi = -1e9f;
    for (std::size_t i = 0; i < r.region.pixels.size(); ++i) {
      const float reg = r.region.pixels[i];
      CHECK((reg < 0) == (s.primitive.pixels[i] < 0));
      if (reg >= 0) lo = std::min(lo, reg), hi = std::max(hi, reg);
    }
    CHECK(lo >= 0);
    CHECK(hi <= 6);
    CHECK(hi > lo);
  }
}

TEST_CASE("dataflow: with --queue-capacity 1 --send-queue 1 rays spill to the host and come back, nothing is lost") {
  for (auto [name, size] : {std::pair{"rings", 1}, std::pair{"mount", 2}}) {
    const testing::BuiltScene b = testing::build_spd(name, size);
    core::RenderParams rp;
    rp.width = 48;
    rp.height = 32;
    const core::RenderResult seq = core::render(b.db, b.grid, rp);
    for (std::uint32_t n : {2u, 3u, 4u, 8u, 12u, 32u, 64u}) {
      CAPTURE(name);
      CAPTURE(n);
      DataflowParams p = params_for(rp, n);
      p.machine.mailbox_capacity = 1;
      p.send_queue_slots = 1;
      const DataflowResult r = render_dataflow(b.db, b.grid, p);
      CHECK(max_diff(r.render.color, seq.color) <= 1e-5f);
      check_counters_match(r.render.stats, seq.stats);
      CHECK(r.host.spilled > 0);
      CHECK(r.host.forwarded == r.host.spilled);
      CHECK(r.spill_fraction() > 0);
      CHECK(r.spill_fraction() <= 1);
      std::uint64_t received = 0, sent = 0;
      for (const NodeFlowStats& s : r.per_node) {
        for (int k = 0; k < kRayKindCount; ++k) received += s.rays_received[k];
        for (int k = 0; k < kRayKindCount; ++k) sent += s.rays_sent[k].messages + s.rays_spilled[k].messages;
      }
      CHECK(received == sent);  // every ray message reached its region
    }
  }
}

TEST_CASE("dataflow: the pixel sums equal sequential's (no contribution lost or doubled)") {
  const testing::BuiltScene b = testing::build_spd("balls", 1);
  core::RenderParams rp;
  rp.width = 32;
  rp.height = 24;
  rp.max_depth = 3;
  const core::RenderResult seq = core::render(b.db, b.grid, rp);
  DataflowParams p = params_for(rp, 5);
  p.machine.mailbox_capacity = 2;
  const DataflowResult r = render_dataflow(b.db, b.grid, p);
  double a = 0, s = 0;
  for (float v : r.render.color.pixels) a += v;
  for (float v : seq.color.pixels) s += v;
  CHECK(a == doctest::Approx(s).epsilon(1e-6));
  CHECK(r.host.waves >= 2);  // termination needs two equal waves
}

TEST_CASE("dataflow: equal regions load the nodes less evenly than balanced ones") {
  const testing::BuiltScene b = testing::build_spd("teapot", 2);
  core::RenderParams rp;
  rp.width = 64;
  rp.height = 64;
  DataflowParams p = params_for(rp, 8);
  p.subsample = 4;
  const DataflowResult bal = render_dataflow(b.db, b.grid, p);
  p.partition = PartitionKind::kEqual;
  const DataflowResult eq = render_dataflow(b.db, b.grid, p);
  // Estimated cost per region: balanced is near-equal, equal-size is not.
  auto spread = [](const DataflowResult& r) {
    double lo = 1e300, hi = 0;
    for (const RegionReport& g : r.regions) lo = std::min(lo, g.estimated_cost), hi = std::max(hi, g.estimated_cost);
    return hi > 0 ? lo / hi : 0.0;
  };
  CHECK(spread(bal) > 0.9);
  CHECK(spread(eq) < spread(bal));
  CHECK(max_diff(bal.render.color, eq.render.color) <= 1e-5f);
}

TEST_CASE("dataflow: a region that does not fit its node fails before the run, naming the sizes") {
  const testing::BuiltScene b = testing::build_spd("tetra", 4);
  core::RenderParams rp;
  rp.width = rp.height = 8;
  DataflowParams p = params_for(rp, 2);
  p.machine.node_memory = 64 * 1024;
  // The run's error message ("" and a failed check if it does not throw).
  const auto failure = [&] {
    try {
      render_dataflow(b.db, b.grid, p);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    FAIL_CHECK("expected an error");
    return std::string();
  };
  std::string what = failure();
  CAPTURE(what);
  CHECK(what.find("dataflow mode: region") != std::string::npos);
  CHECK(what.find("primitives") != std::string::npos);
  CHECK(what.find("--node-memory is 64 KiB") != std::string::npos);
  // An adaptive local grid is named as one, with its sub-grids and leaf cells.
  p.grid = grid_params(core::GridKind::kAdaptive, 8);
  what = failure();
  CHECK(what.find("dataflow mode: region") != std::string::npos);
  CHECK(what.find("an adaptive grid (") != std::string::npos);
  CHECK(what.find("sub-grids") != std::string::npos);
  CHECK(what.find("leaf cells) with") != std::string::npos);
  CHECK(what.find("--node-memory is 64 KiB") != std::string::npos);
}

TEST_CASE("dataflow: bad parameters are rejected") {
  const testing::BuiltScene b = testing::build_spd("tetra", 1);
  core::RenderParams rp;
  rp.width = rp.height = 8;
  DataflowParams p = params_for(rp, 2);
  p.subsample = 0;
  CHECK_THROWS_AS(render_dataflow(b.db, b.grid, p), std::invalid_argument);
  CHECK_THROWS_AS(parse_partition("median"), std::invalid_argument);
  CHECK(parse_partition("equal") == PartitionKind::kEqual);
}

TEST_CASE("dataflow: a small model on a huge floor: the estimate is charged again where the work is, and balanced regions share it") {
  const core::Database db = teapot_on_floor(3, 1000.0f);
  for (const core::GridKind kind : {core::GridKind::kUniform, core::GridKind::kAdaptive}) {
    CAPTURE(core::grid_kind_name(kind));
    const core::Grid host = core::build_grid(db, grid_params(kind));
    core::RenderParams rp;
    rp.width = 64;
    rp.height = 48;
    const core::RenderResult seq = core::render(db, host, rp);
    DataflowParams p = params_for(rp, 8);
    p.subsample = 4;
    p.grid = grid_params(kind);
    const DataflowResult r = render_dataflow(db, host, p);
    CHECK(max_diff(r.render.color, seq.color) <= 1e-5f);
    check_counters_match(r.render.stats, seq.stats);
    // The floor spans 1000 model widths on screen; the charged part a few.
    REQUIRE(r.estimate.refined);
    const ScreenRect& all = r.extent;
    const ScreenRect& work = r.estimate.cost.extent;
    CHECK((work.x1 - work.x0) * 4 < (all.x1 - all.x0));
    double lo = 1e300, hi = 0, total = 0;
    for (const RegionReport& g : r.regions) {
      lo = std::min(lo, g.estimated_cost), hi = std::max(hi, g.estimated_cost);
      total += g.estimated_cost;
      // Every finite rectangle's outer sides reach the whole scene's extent.
      if (std::isinf(g.rect.x0)) CHECK(g.finite.x0 <= all.x0);
      if (std::isinf(g.rect.x1)) CHECK(g.finite.x1 >= all.x1);
    }
    CHECK(total == doctest::Approx(r.estimate.cost.total()).epsilon(1e-6));
    CHECK(lo / hi > 0.8);  // one cost cell held the whole model before
  }
}
