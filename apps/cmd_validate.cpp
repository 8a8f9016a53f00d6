// `raynode validate SCENE`: grid versus Embree on >= 1M rays (core/validate.h).
// Exit status 1 on any mismatch.
#include <fmt/core.h>

#include <nlohmann/json.hpp>
#include <stdexcept>

#include "apps/commands.h"
#include "apps/output_files.h"
#include "apps/run_info.h"
#include "core/database.h"
#include "core/embree_scene.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/scene_view.h"
#include "core/validate.h"

namespace raynode::apps {

namespace {

struct ValidateOptions {
  core::SceneSource source = tracing_source();
  std::string json;  ///< --json: "" none, "-" stdout, else a file
  bool quiet = false;
  core::ValidateParams params;
  float density = core::GridParams{}.density;
  bool skip_empty = core::GridParams{}.skip_empty;
  GridChoice grid;  ///< --grid (default adaptive)
};

nlohmann::json counts_json(const core::ValidateCounts& c) {
  return {{"rays", c.rays},
          {"grid_hits", c.grid_hits},
          {"embree_hits", c.embree_hits},
          {"mismatches", c.mismatches()},
          {"hit_vs_miss", c.hit_vs_miss},
          {"miss_vs_hit", c.miss_vs_hit},
          {"t_mismatch", c.t_mismatch},
          {"any_hit_mismatch", c.any_hit_mismatch},
          {"other_primitive_same_t", c.other_primitive},
          {"oracle_errors", c.oracle_errors},
          {"max_t_rel_error", c.max_t_rel_error}};
}

void run_validate(const ValidateOptions& o) {
  OutputFiles files(core::is_scene_file(o.source.spec) ? std::vector<std::string>{o.source.spec}
                                                       : std::vector<std::string>{});
  const std::size_t json_out = o.json.empty() ? 0 : files.add(o.json, "--json file", true);
  const core::Scene scene = core::load_scene(o.source);
  const core::Database db = core::make_database(scene);
  if (db.primitives.empty())  // nothing to compare: say so instead of "zero mismatches"
    throw std::runtime_error(fmt::format("{}: the scene has no primitives to validate", o.source.spec));
  core::GridParams gp;
  set_grid_density(gp, o.density);
  gp.skip_empty = o.skip_empty;
  gp.kind = grid_kind_for(o.grid);
  gp = core::grid_params_for_packed_cells(gp, o.params.pack_min);
  const core::Grid grid = core::build_grid(db, gp);
  const core::EmbreeScene embree(db);
  const core::ValidateReport r = [&] {
    try {
      core::ValidateParams params = o.params;  // a side 0: --width or --height alone, the view's aspect
      core::fit_resolution(params.width, params.height, core::render_view(db));
      return core::validate_grid(db, grid, embree, params);
    } catch (const std::exception& e) {  // a default camera or a ray out of Embree's range: name the scene
      throw std::runtime_error(o.source.spec + ": " + e.what());
    }
  }();

  if (!o.json.empty()) {
    nlohmann::json j;
    j["scene"] = o.source.spec;
    j["tessellate"] = o.source.tessellate;
    j["floor"] = o.source.floor;
    j["primitives"] = db.primitives.size();
    j["grid_resolution"] = {grid.info.res[0], grid.info.res[1], grid.info.res[2]};
    j["grid"] = grid_json(grid);
    j["pack_cells"] = o.params.pack_min;
    j["t_rel_tolerance"] = o.params.t_rel;
    j["primary"] = counts_json(r.primary);
    j["random"] = counts_json(r.random);
    j["secondary"] = counts_json(r.secondary);
    j["reflected"] = counts_json(r.reflected);
    j["scattered"] = counts_json(r.scattered);
    j["total"] = counts_json(r.total);
    j["rays"] = r.total.rays;
    j["hits"] = r.total.grid_hits;
    j["mismatches"] = r.total.mismatches();
    nlohmann::json ex = nlohmann::json::array();
    for (const auto& e : r.examples)
      ex.push_back({{"set", e.set},
                    {"origin", {e.ray.origin.x, e.ray.origin.y, e.ray.origin.z}},
                    {"direction", {e.ray.direction.x, e.ray.direction.y, e.ray.direction.z}},
                    {"grid", {{"t", e.grid.found() ? double(e.grid.t) : -1.0}, {"primitive", int64_t(e.grid.found() ? e.grid.primitive : -1)}}},
                    {"embree", {{"t", e.embree.found() ? double(e.embree.t) : -1.0}, {"primitive", int64_t(e.embree.found() ? e.embree.primitive : -1)}}}});
    j["examples"] = ex;
    j["run"] = run_json();
    files.text(json_out, j.dump(2) + "\n");
    files.commit();
  }
  if (o.json != "-" && !o.quiet) {
    fmt::print("validate {}: {} primitives, grid {}, t tolerance {} relative\n", o.source.spec,
               db.primitives.size(), grid_summary(grid), o.params.t_rel);
    fmt::print("{:<10} {:>9} {:>9} {:>9} {:>10} {:>11} {:>10} {:>10} {:>12} {:>11}\n", "rays", "count", "grid hit",
               "embree", "mismatch", "hit/miss", "miss/hit", "t", "max t err", "oracle err");
    auto row = [](const char* name, const core::ValidateCounts& c) {
      fmt::print("{:<10} {:>9} {:>9} {:>9} {:>10} {:>11} {:>10} {:>10} {:>12.3g} {:>11}\n", name, c.rays,
                 c.grid_hits, c.embree_hits, c.mismatches(), c.hit_vs_miss, c.miss_vs_hit, c.t_mismatch,
                 c.max_t_rel_error, c.oracle_errors);
    };
    row("primary", r.primary);
    row("random", r.random);
    row("reflected", r.reflected);
    row("scattered", r.scattered);
    row("secondary", r.secondary);
    row("total", r.total);
    for (const auto& e : r.examples)
      fmt::print("  mismatch ({}): o=({}, {}, {}) d=({}, {}, {}) grid t={} prim={} embree t={} prim={}\n", e.set,
                 e.ray.origin.x, e.ray.origin.y, e.ray.origin.z, e.ray.direction.x, e.ray.direction.y,
                 e.ray.direction.z, e.grid.t, int64_t(e.grid.found() ? e.grid.primitive : -1), e.embree.t,
                 int64_t(e.embree.found() ? e.embree.primitive : -1));
    fmt::print("oracle err = Embree disagreed and the double-precision brute-force referee sided with the grid\n");
    fmt::print("{}\n", r.total.mismatches() == 0 ? "OK: zero mismatches" : "FAILED: mismatches found");
  }
  if (r.total.mismatches() != 0) throw std::runtime_error(fmt::format("{} mismatches", r.total.mismatches()));
}

}  // namespace

void register_validate_command(CLI::App& app) {
  auto o = std::make_shared<ValidateOptions>();
  CLI::App* c = app.add_subcommand(
      "validate",
      "Fire >= 1M rays (primary, random, secondary from real hit points) through the grid (--grid) and "
      "Embree and count mismatches; exit 1 if any");
  add_scene_options(*c, o->source);
  add_camera_options(*c, o->source.view);
  add_json_option(*c, o->json, "The counts");
  c->add_flag("--quiet,-q", o->quiet, "Print nothing; the exit status says whether any ray mismatched");
  CLI::Option* w = c->add_option("--width", o->params.width,
                                 "Primary rays: image width in pixels (given alone, the height keeps the view's "
                                 "aspect ratio) [default: 512]")
                        ->check(CLI::Range(1, 16384));
  CLI::Option* h = c->add_option("--height", o->params.height,
                                 "Primary rays: image height in pixels (given alone, the width keeps the view's "
                                 "aspect ratio) [default: 512]")
                        ->check(CLI::Range(1, 16384));
  c->add_option("--random-rays", o->params.random_rays, "Number of random rays")->check(CLI::Range(0, 100000000));
  c->add_option("--seed", o->params.seed, "Random seed");
  c->add_option("--t-tolerance", o->params.t_rel, "Relative tolerance on the hit distance")
      ->check(finite_range(0, 1));
  add_grid_density_option(*c, o->density);
  add_grid_option(*c, o->grid);
  add_skip_empty_option(*c, o->skip_empty);
  add_pack_cells_option(*c, o->params.pack_min);
  c->callback([o, w, h] {
    if (w->count() > 0 && h->count() == 0) o->params.height = 0;  // run_validate fits it to the view
    if (h->count() > 0 && w->count() == 0) o->params.width = 0;
    run_validate(*o);
  });
}

}  // namespace raynode::apps
