// `raynode bench accel SCENE...`: rays per second of the grid (--grid) and of
// Embree, one thread, the same rays: primary rays through each pixel centre
// (closest hit), shadow rays from their hits to every light (any hit), and
// mirror rays from their hits (closest hit). Best of --repeat runs.
#include <fmt/core.h>

#include <chrono>
#include <memory>
#include <nlohmann/json.hpp>
#include <vector>

#include "apps/commands.h"
#include "apps/output_files.h"
#include "apps/run_info.h"
#include "core/camera.h"
#include "core/database.h"
#include "core/direct_view.h"
#include "core/embree_scene.h"
#include "core/grid.h"
#include "core/intersect.h"
#include "core/render.h"
#include "core/spawn.h"
#include "core/traverse.h"

namespace raynode::apps {

namespace {

struct BenchOptions {
  std::vector<std::string> scenes;
  int tessellate = 0;
  double floor = 0;         ///< --floor K (0: none)
  core::ViewOverride view;  ///< --eye, --at, --up, --fov
  int width = 512, height = 512;
  int repeat = 3;
  float density = core::GridParams{}.density;
  bool skip_empty = core::GridParams{}.skip_empty;
  GridChoice grid;  ///< --grid (default adaptive)
  std::uint32_t pack_min = core::kDefaultPackMin;  ///< --pack-cells; 0 = off
  std::string json;  ///< --json: "" none, "-" stdout, else a file
};

struct RaySet {
  std::vector<core::Ray> closest;  // primary + mirror rays
  std::vector<core::Ray> shadow;   // any-hit rays
  // The triangle each ray leaves, for the grid's queries (intersect_closest's
  // origin_triangle; kNoPrimitive for eye rays), as the tracer passes it.
  std::vector<std::uint32_t> closest_origin, shadow_origin;
};

RaySet make_rays(const core::Database& db, const core::Grid& grid, int w, int h) {
  RaySet rs;
  const core::Camera cam(core::render_view(db), w, h);
  const core::DirectView dv(db, grid);
  core::TraversalScratch scratch;
  std::vector<core::Ray> mirror;
  std::vector<std::uint32_t> mirror_origin;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const core::Ray r = cam.ray_through(float(x) + 0.5f, float(y) + 0.5f);
      rs.closest.push_back(r);
      rs.closest_origin.push_back(core::kNoPrimitive);
      core::Hit hit;
      if (!core::intersect_closest(dv, r, hit, scratch)) continue;
      const core::Primitive& prim = db.primitives[hit.primitive];
      // Spawned as the tracer spawns them (surface_frame, shade_hit).
      const core::SurfaceFrame f = core::surface_frame(dv, prim, r, hit);
      for (const core::Light& l : db.lights) {
        rs.shadow.push_back(core::Ray{f.above, l.position - f.above, 0.0f, 1.0f});
        rs.shadow_origin.push_back(f.leaving(rs.shadow.back()));
      }
      const core::Vec3& n = f.nf;
      mirror.push_back(core::Ray{f.above, r.direction - n * (2.0f * core::dot(r.direction, n)), 0.0f, core::kInfinity});
      mirror_origin.push_back(f.leaving(mirror.back()));
    }
  rs.closest.insert(rs.closest.end(), mirror.begin(), mirror.end());
  rs.closest_origin.insert(rs.closest_origin.end(), mirror_origin.begin(), mirror_origin.end());
  return rs;
}

// The best of `repeat` timed runs of f(), each after an untimed before()
// (which frees what the last run made, so that its freeing is not timed).
template <class B, class F>
double best_seconds(int repeat, B&& before, F&& f) {
  double best = 1e30;
  for (int i = 0; i < repeat; ++i) {
    before();
    const auto t0 = std::chrono::steady_clock::now();
    f();
    best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  return best;
}

template <class F>
double best_seconds(int repeat, F&& f) {
  return best_seconds(repeat, [] {}, f);
}

void run_bench(const BenchOptions& o) {
  std::vector<std::string> inputs;
  for (const std::string& spec : o.scenes)
    if (core::is_scene_file(spec)) inputs.push_back(spec);
  OutputFiles files(inputs);
  const std::size_t json_out = o.json.empty() ? 0 : files.add(o.json, "--json file", true);
  const bool text = o.json != "-";  // the table, unless the JSON goes to stdout
  nlohmann::json out = nlohmann::json::array();
  if (text)
    fmt::print("{:<12} {:>9} {:>12} {:>9} {:>10} {:>11} {:>11} {:>12} {:>12} {:>8} {:>8}\n", "scene", "prims",
               "grid res", "build s", "rays", "cells/ray", "tests/ray", "grid Mray/s", "embree Mray/s", "ratio",
               "memory");
  for (const std::string& spec : o.scenes) {
    core::SceneSource source = tracing_source(spec, o.tessellate);  // the rays render traces
    source.view = o.view;
    source.floor = o.floor;
    const core::Scene scene = core::load_scene(source);
    const core::Database db = core::make_database(scene);
    core::GridParams gp;
    set_grid_density(gp, o.density);
    gp.skip_empty = o.skip_empty;
    gp.kind = grid_kind_for(o.grid);
    gp = core::grid_params_for_packed_cells(gp, o.pack_min);
    core::Grid grid;
    // Both builds run on all the host's threads (the grid's and Embree's BVH,
    // committed in its constructor, both with oneTBB); the best of --repeat.
    const double build_s =
        best_seconds(o.repeat, [&] { grid = {}; }, [&] { grid = core::build_grid(db, gp); });
    std::unique_ptr<core::EmbreeScene> embree_scene;
    const double embree_build_s = best_seconds(
        o.repeat, [&] { embree_scene.reset(); }, [&] { embree_scene = std::make_unique<core::EmbreeScene>(db); });
    const core::EmbreeScene& embree = *embree_scene;
    int width = o.width, height = o.height;  // a side 0: --width or --height alone, the view's aspect
    core::fit_resolution(width, height, core::render_view(db));
    const RaySet rs = make_rays(db, grid, width, height);
    core::CellBlocks blocks;
    if (o.pack_min > 0) blocks = core::build_cell_blocks(db, grid, o.pack_min, core::PackKinds::kTrianglesAndSpheres);
    const core::DirectView dv(db, grid, o.pack_min > 0 ? &blocks : nullptr);
    core::TraversalScratch scratch;
    std::uint64_t sink = 0;
    // Grid and Embree runs alternate, so that a burst of load on a noisy
    // machine falls on both rather than on one accelerator's runs.
    double grid_s = 1e30, embree_s = 1e30;
    for (int i = 0; i < o.repeat; ++i) {
      scratch.stats = {};
      grid_s = std::min(grid_s, best_seconds(1, [&] {
                          core::Hit h;
                          for (std::size_t i = 0; i < rs.closest.size(); ++i)
                            sink += core::intersect_closest(dv, rs.closest[i], h, scratch, rs.closest_origin[i]);
                          for (std::size_t i = 0; i < rs.shadow.size(); ++i)
                            sink += core::intersect_any(dv, rs.shadow[i], scratch, rs.shadow_origin[i]);
                        }));
      embree_s = std::min(embree_s, best_seconds(1, [&] {
                            core::Hit h;
                            for (const core::Ray& r : rs.closest) sink += embree.intersect_closest(r, h);
                            for (const core::Ray& r : rs.shadow) sink += embree.intersect_any(r);
                          }));
    }
    const core::TraversalStats& st = scratch.stats;  // one run's counts
    const double n = double(rs.closest.size() + rs.shadow.size());
    const double ratio = grid_s / embree_s;
    // The grid's structure with its packed cells (their triangle and sphere
    // copies) against Embree's BVH with the copies in its leaves.
    const std::size_t grid_bytes = grid.bytes() + blocks.bytes(), embree_bytes = embree.build_bytes();
    const double memory_ratio = embree_bytes ? double(grid_bytes) / double(embree_bytes) : 0.0;
    nlohmann::json j = {{"scene", spec},
                        {"tessellate", o.tessellate},
                        {"floor", o.floor},
                        {"primitives", db.primitives.size()},
                        {"grid_resolution", {grid.info.res[0], grid.info.res[1], grid.info.res[2]}},
                        {"grid_references", grid.references()},
                        {"grid_kind", core::grid_kind_name(grid.kind())},
                        {"grid", grid_json(grid)},
                        {"grid_build_s", build_s},
                        {"embree_build_s", embree_build_s},
                        {"grid_bytes", grid_bytes},
                        {"packed_bytes", blocks.bytes()},
                        {"embree_bytes", embree_bytes},
                        {"grid_over_embree_memory", memory_ratio},
                        {"skip_empty", o.skip_empty},
                        {"pack_cells", o.pack_min},
                        {"packed_blocks", blocks.blocks.size()},
                        {"packed_sphere_blocks", blocks.sphere_blocks.size()},
                        {"rays", std::uint64_t(n)},
                        {"closest_rays", rs.closest.size()},
                        {"shadow_rays", rs.shadow.size()},
                        {"grid_rays_per_s", n / grid_s},
                        {"embree_rays_per_s", n / embree_s},
                        {"grid_over_embree_time", ratio},
                        {"cells_per_ray", double(st.cells_visited) / n},
                        {"jumps_per_ray", double(st.empty_jumps) / n},
                        {"tests_per_ray", double(st.triangle_tests + st.sphere_tests + st.cone_tests) / n},
                        {"empty_cells", grid.empty_cells()},
                        {"checksum", sink},
                        {"run", run_json()}};
    out.push_back(j);
    if (text)
      fmt::print("{:<12} {:>9} {:>12} {:>9.2f} {:>10} {:>11.1f} {:>11.1f} {:>12.2f} {:>12.2f} {:>8.2f} {:>8.2f}\n",
                 spec, db.primitives.size(),
                 fmt::format("{}x{}x{}", grid.info.res[0], grid.info.res[1], grid.info.res[2]), build_s,
                 std::uint64_t(n), double(st.cells_visited) / n,
                 double(st.triangle_tests + st.sphere_tests + st.cone_tests) / n, n / grid_s * 1e-6,
                 n / embree_s * 1e-6, ratio, memory_ratio);
  }
  if (!o.json.empty()) {
    files.text(json_out, out.dump(2) + "\n");
    files.commit();
  }
  if (text)
    fmt::print("ratio = grid time / Embree time (one thread, same rays; lower is better); memory = the grid's bytes "
               "with its packed cells / Embree's BVH bytes; grid res = the {} grid{}\n",
               core::grid_kind_name(grid_kind_for(o.grid)),
               grid_kind_for(o.grid) == core::GridKind::kAdaptive ? "'s top grid" : "");
}

}  // namespace

void register_bench_command(CLI::App& app) {
  CLI::App* bench = app.add_subcommand("bench", "Benchmarks (timings are never pass/fail tests)");
  bench->require_subcommand(1);
  auto o = std::make_shared<BenchOptions>();
  CLI::App* c = bench->add_subcommand(
      "accel", "Rays/s of the grid (--grid) vs Embree, one thread, same rays (primary, shadow, mirror)");
  c->add_option("scenes", o->scenes, "Scenes (NFF or mesh files, or SPD name[:size])")->required();
  c->add_option("--tessellate,-t", o->tessellate, "Tessellate spheres and cones (SPD -t R)")
      ->check(CLI::Range(0, 1000));
  add_floor_option(*c, o->floor);
  add_camera_options(*c, o->view);
  CLI::Option* w = c->add_option("--width", o->width,
                                 "Image width for primary rays (given alone, the height keeps the view's aspect "
                                 "ratio) [default: 512]")
                        ->check(CLI::Range(1, 8192));
  CLI::Option* h = c->add_option("--height", o->height,
                                 "Image height for primary rays (given alone, the width keeps the view's aspect "
                                 "ratio) [default: 512]")
                        ->check(CLI::Range(1, 8192));
  c->add_option("--repeat", o->repeat, "Runs per accelerator; the best is kept")->check(CLI::Range(1, 100));
  add_grid_density_option(*c, o->density);
  add_grid_option(*c, o->grid);
  add_skip_empty_option(*c, o->skip_empty);
  add_pack_cells_option(*c, o->pack_min);
  add_json_option(*c, o->json, "One object per scene");
  c->callback([o, w, h] {
    if (w->count() > 0 && h->count() == 0) o->height = 0;  // run_bench fits it to each scene's view
    if (h->count() > 0 && w->count() == 0) o->width = 0;
    run_bench(*o);
  });
}

}  // namespace raynode::apps
