// `raynode scene info SCENE [--json]` and `raynode scene write SCENE -o FILE`.
#include <fmt/core.h>

#include <chrono>
#include <nlohmann/json.hpp>

#include "apps/commands.h"
#include "apps/run_info.h"
#include "apps/output_files.h"
#include "apps/watchdog.h"
#include "core/cell_blocks.h"
#include "core/database.h"
#include "core/grid.h"
#include "core/nff.h"

namespace raynode::apps {

namespace {

struct InfoOptions {
  core::SceneSource source;
  std::string json;  ///< --json: "" none, "-" stdout, else a file
  std::string grid;  ///< --grid [adaptive|uniform]: "" = no grid, "adaptive" when given bare
};

struct WriteOptions {
  core::SceneSource source;
  std::string output;
  double timeout_s = 0;
};

void run_info(const InfoOptions& o) {
  const core::Scene scene = core::load_scene(o.source);
  const core::SceneCounts c = scene.counts();
  const core::Bounds3 b = scene.bounds();
  nlohmann::json j;
  j["scene"] = o.source.spec;
  j["tessellate"] = o.source.tessellate;
  j["floor"] = o.source.floor;
  j["counts"] = {{"polygons", c.polygons},   {"patches", c.patches}, {"spheres", c.spheres},
                 {"cones", c.cones},         {"lights", c.lights},   {"materials", c.materials},
                 {"dropped_degenerate", c.dropped_degenerate}};
  j["primitives"] = scene.shapes.size();
  if (!b.empty())
    j["bounds"] = {{"lower", {b.lower.x, b.lower.y, b.lower.z}}, {"upper", {b.upper.x, b.upper.y, b.upper.z}}};
  if (scene.has_view) j["view"] = {{"width", scene.view.width}, {"height", scene.view.height}};
  const core::Database db = core::make_database(scene);
  const core::DatabaseCounts dc = db.counts();
  j["database"] = {{"triangles", dc.triangles},
                   {"spheres", dc.spheres},
                   {"cones", dc.cones},
                   {"bytes", db.bytes()},
                   {"dropped_degenerate_triangles", db.dropped_degenerate_triangles}};
  std::string grid_line;
  if (!o.grid.empty()) {
    core::GridParams gp;
    gp.kind = o.grid == "uniform" ? core::GridKind::kUniform : core::GridKind::kAdaptive;
    gp = core::grid_params_for_packed_cells(gp, core::kDefaultPackMin);  // render's default: packed cells
    const auto start = std::chrono::steady_clock::now();
    const core::Grid g = core::build_grid(db, gp);
    const double build_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    j["grid"] = grid_json(g);
    j["grid"]["build_s"] = build_s;
    grid_line = fmt::format("{}, {} empty leaf cells, {:.1f} KiB, built in {:.3f} s", grid_summary(g), g.empty_cells(),
                            g.bytes() / 1024.0, build_s);
    const std::vector<GridLevel> levels = grid_levels(g);
    if (g.kind() == core::GridKind::kAdaptive)
      for (std::size_t i = 0; i < levels.size(); ++i)
        grid_line += fmt::format("\n  level {}   {} grid{}, {} cells, {} leaf cells ({} empty), {} references", i,
                                 levels[i].grids, levels[i].grids == 1 ? "" : "s", levels[i].cells,
                                 levels[i].leaf_cells, levels[i].empty_cells, levels[i].references);
  }
  if (!o.json.empty()) {
    j["run"] = run_json();
    OutputFiles files(core::is_scene_file(o.source.spec) ? std::vector<std::string>{o.source.spec}
                                                         : std::vector<std::string>{});
    files.text(files.add(o.json, "--json file", true), j.dump(2) + "\n");
    files.commit();
    if (o.json == "-") return;
  }
  fmt::print("scene       {}{}\n", o.source.spec,
             o.source.tessellate ? fmt::format(" (tessellated, R={})", o.source.tessellate) : "");
  fmt::print("polygons    {}\npatches     {}\nspheres     {}\ncones       {}\nlights      {}\nmaterials   {}\n",
             c.polygons, c.patches, c.spheres, c.cones, c.lights, c.materials);
  if (c.dropped_degenerate) fmt::print("dropped     {} zero-area polygons\n", c.dropped_degenerate);
  fmt::print("database    {} triangles, {} spheres, {} cones, {:.1f} KiB\n", dc.triangles, dc.spheres, dc.cones,
             db.bytes() / 1024.0);
  if (!o.grid.empty()) fmt::print("grid        {}\n", grid_line);
}

}  // namespace

void register_scene_commands(CLI::App& app) {
  CLI::App* scene =
      app.add_subcommand("scene", "Inspect or write scenes (NFF or mesh files, or built-in SPD generators)");
  scene->require_subcommand(1);

  auto info = std::make_shared<InfoOptions>();
  CLI::App* ci = scene->add_subcommand("info", "Print counts per entity kind (as the SPD programs count them)");
  add_scene_options(*ci, info->source);
  add_json_option(*ci, info->json, "The counts and sizes");
  // A flag, so that `--grid SCENE` never takes the scene as its value.
  ci->add_flag("--grid{adaptive}", info->grid,
               "Also build the grid that render's default mode builds (packed cells) and print its structure "
               "(levels, cells and leaf cells per level, references, bytes, build time): --grid or --grid=adaptive, "
               "or --grid=uniform")
      ->check(CLI::IsMember({"adaptive", "uniform"}));
  ci->callback([info] { run_info(*info); });

  auto wr = std::make_shared<WriteOptions>();
  CLI::App* cw = scene->add_subcommand("write", "Write a scene as NFF (.nff, or .nff.gz for gzip)");
  add_scene_options(*cw, wr->source);
  cw->add_option("-o,--output", wr->output, "Output NFF file")->required();
  cw->add_option("--timeout", wr->timeout_s, "Stop with an error (exit 1, no file written) after this many wall "
                                            "seconds from start (0 = never)")
      ->check(finite_range(0, kNoBound));
  cw->callback([wr] {
    start_timeout_watchdog(wr->timeout_s);
    // The output is checked before the scene is read; "-" is stdout (plain NFF).
    OutputFiles files(core::is_scene_file(wr->source.spec) ? std::vector<std::string>{wr->source.spec}
                                                          : std::vector<std::string>{});
    const std::size_t out = files.add(wr->output, "NFF file", true);
    const core::Scene s = core::load_scene(wr->source);
    const bool gzip = wr->output.size() >= 3 && wr->output.compare(wr->output.size() - 3, 3, ".gz") == 0;
    files.file(out, [&](const std::string& file_path) { core::write_nff_into(file_path, s, gzip, wr->output); });
    files.commit();
  });
}

}  // namespace raynode::apps
