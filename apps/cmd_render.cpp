// `raynode render SCENE`: the Whitted renderer (core/render.h) in sequential
// or shared-memory mode, writing the image through OpenImageIO (format by
// extension), optionally a depth AOV (NAME.depth.exr) and JSON statistics.
#include <fmt/core.h>

#include <chrono>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "apps/commands.h"
#include "core/database.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/scene_source.h"
#include "imageio/write_image.h"

namespace raynode::apps {

namespace {

struct RenderOptions {
  core::SceneSource source;
  std::string output = "render.png";
  std::string mode = "sequential";
  int width = 0, height = 0;
  int spp = 1;
  int max_depth = 5;
  float min_weight = 0.0f;
  std::string stats_path;
  std::vector<std::string> aovs;
  bool quiet = false;
};

/// out.png -> out.depth.exr (same directory).
std::string aov_path(const std::string& output, const std::string& aov) {
  std::filesystem::path p(output);
  p.replace_extension();
  return p.string() + "." + aov + ".exr";
}

void run_render(const RenderOptions& o) {
  core::RenderParams params;
  params.mode = core::parse_render_mode(o.mode);
  params.width = o.width;
  params.height = o.height;
  params.spp = o.spp;
  params.max_depth = o.max_depth;
  params.min_weight = o.min_weight;
  for (const std::string& a : o.aovs) {
    if (a == "depth") params.depth_aov = true;
    else throw UsageError("unknown AOV '" + a + "' (supported: depth)");
  }
  if (!imageio::is_float_format(o.output) && std::filesystem::path(o.output).extension().empty())
    throw UsageError("output '" + o.output + "' has no extension to choose the image format");
  if (!imageio::can_write_format(o.output))
    throw UsageError("no image writer for the extension of '" + o.output + "' (try .png, .exr, .tif, .ppm)");

  const core::Scene scene = core::load_scene(o.source);
  const core::Database db = core::make_database(scene);
  const auto t_build = std::chrono::steady_clock::now();
  const core::Grid grid = core::build_grid(db);
  const double build_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_build).count();

  const auto t0 = std::chrono::steady_clock::now();
  const std::clock_t c0 = std::clock();
  const core::RenderResult result = core::render(db, grid, params);
  const double cpu_s = double(std::clock() - c0) / CLOCKS_PER_SEC;
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  imageio::write_image(o.output, result.color);
  std::string depth_file;
  if (params.depth_aov) {
    depth_file = aov_path(o.output, "depth");
    imageio::write_image(depth_file, result.depth);
  }

  const core::RenderStats& s = result.stats;
  if (!o.stats_path.empty()) {
    const core::SceneCounts sc = scene.counts();
    const core::DatabaseCounts dc = db.counts();
    nlohmann::json j = {
        {"scene", o.source.spec},
        {"tessellate", o.source.tessellate},
        {"mode", core::render_mode_name(params.mode)},
        {"nodes", 1},
        {"width", result.color.width},
        {"height", result.color.height},
        {"spp", params.spp},
        {"max_depth", params.max_depth},
        {"min_weight", params.min_weight},
        {"rays",
         {{"primary", s.rays.primary},
          {"shadow", s.rays.shadow},
          {"reflected", s.rays.reflected},
          {"refracted", s.rays.refracted},
          {"total", s.rays.total()}}},
        {"skipped",
         {{"reflection_ks0", s.skipped.reflection_ks0},
          {"refraction_t0", s.skipped.refraction_t0},
          {"shadow_backfacing", s.skipped.shadow_backfacing},
          {"highlight_marker", s.skipped.highlight_marker},
          {"depth_limit", s.skipped.depth_limit},
          {"min_weight", s.skipped.min_weight}}},
        {"tests",
         {{"triangle", s.traversal.triangle_tests},
          {"sphere", s.traversal.sphere_tests},
          {"cone", s.traversal.cone_tests}}},
        {"cells_visited", s.traversal.cells_visited},
        {"mailbox_skips", s.traversal.mailbox_skips},
        {"time", {{"wall_s", wall_s}, {"cpu_s", cpu_s}, {"grid_build_s", build_s}}},
        {"scene_counts",
         {{"polygons", sc.polygons},
          {"patches", sc.patches},
          {"spheres", sc.spheres},
          {"cones", sc.cones},
          {"lights", sc.lights},
          {"materials", sc.materials}}},
        {"database",
         {{"primitives", db.primitives.size()},
          {"triangles", dc.triangles},
          {"spheres", dc.spheres},
          {"cones", dc.cones}}},
        {"grid_resolution", {grid.info.res[0], grid.info.res[1], grid.info.res[2]}},
        {"output", o.output},
    };
    if (!depth_file.empty()) j["depth_output"] = depth_file;
    std::ofstream f(o.stats_path);
    if (!f) throw std::runtime_error("cannot write " + o.stats_path);
    f << j.dump(2) << "\n";
    if (!f) throw std::runtime_error("error writing " + o.stats_path);
  }
  if (!o.quiet) {
    fmt::print("{}: {}x{} spp {}x{} mode {} in {:.3f} s wall ({:.3f} s cpu)\n", o.output, result.color.width,
               result.color.height, params.spp, params.spp, core::render_mode_name(params.mode), wall_s, cpu_s);
    fmt::print("rays: {} primary, {} shadow, {} reflected, {} refracted ({} total)\n", s.rays.primary,
               s.rays.shadow, s.rays.reflected, s.rays.refracted, s.rays.total());
    if (!depth_file.empty()) fmt::print("depth: {}\n", depth_file);
  }
}

}  // namespace

void register_render_command(CLI::App& app) {
  auto o = std::make_shared<RenderOptions>();
  CLI::App* c = app.add_subcommand("render", "Render a scene (Whitted ray tracing, SPD shading) to an image");
  add_scene_options(*c, o->source);
  c->add_option("-o,--output", o->output, "Output image; format by extension (png, exr, tif, ppm, ...)");
  c->add_option("--mode", o->mode, "sequential (one thread) or shared (TBB threads over 16x16 tiles)")
      ->check(CLI::IsMember({"sequential", "shared"}));
  c->add_option("--width", o->width, "Image width in pixels (default: the scene's view)")->check(CLI::Range(1, 16384));
  c->add_option("--height", o->height, "Image height in pixels (default: the scene's view)")
      ->check(CLI::Range(1, 16384));
  c->add_option("--spp", o->spp, "N: N x N stratified samples per pixel")->check(CLI::Range(1, 64));
  c->add_option("--max-depth", o->max_depth, "Ray levels, eye ray = 1 (SPD: 5)")->check(CLI::Range(1, 64));
  c->add_option("--min-weight", o->min_weight, "Skip child rays whose weight is below this (0 = off)")
      ->check(CLI::Range(0.0f, 1.0f));
  c->add_option("--stats", o->stats_path, "Write counters and timings as JSON to this file");
  c->add_option("--aov", o->aovs, "Extra outputs: depth (written as NAME.depth.exr)")
      ->check(CLI::IsMember({"depth"}));
  c->add_flag("--quiet,-q", o->quiet, "Print nothing on success");
  c->callback([o] { run_render(*o); });
}

}  // namespace raynode::apps
