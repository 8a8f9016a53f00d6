// `raynode render SCENE`: the Whitted renderer (core/render.h) in sequential
// or shared-memory mode over the grid (--grid) or Embree (--accel), writing
// the image through OpenImageIO (format by extension), optional AOVs
// (NAME.depth.exr, NAME.normal.exr, NAME.primitive.exr), JSON statistics
// and a progress line on stderr.
//
// Data flow: SCENE -> Scene -> Database -> accelerator (Grid or EmbreeScene)
// -> render_frame (the one mode dispatch) -> RenderResult -> image files.
#include <fmt/core.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <tuple>
#include <chrono>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <cerrno>
#include <cstring>
#include <unistd.h>

#include "apps/commands.h"
#include "apps/node_runs.h"
#include "apps/output_files.h"
#include "apps/progress.h"
#include "apps/run_summary.h"
#include "apps/watchdog.h"
#include "core/database.h"
#include "core/direct_view.h"
#include "core/embree_scene.h"
#include "core/embree_view.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/scene_source.h"
#include "dataflow/dataflow.h"
#include "imageio/false_color.h"
#include "imageio/write_image.h"
#include "nodes/machine.h"
#include "nodes/network.h"
#include "nodes/replicated.h"
#include "svm/svm.h"

namespace raynode::apps {

namespace {

struct RenderOptions {
  core::SceneSource source;
  std::string output = "render.png";
  std::string mode = "sequential";
  std::string accel = "grid";
  bool skip_empty = core::GridParams{}.skip_empty;
  GridChoice grid;  ///< --grid (default adaptive)
  std::uint32_t pack_min = core::kDefaultPackMin;  ///< --pack-cells; 0 = off
  bool pack_given = false;  ///< --pack-cells was on the command line (svm packs only when asked)
  int nodes = 1;
  int width = 0, height = 0;
  int spp = 1;
  int max_depth = 5;
  float min_weight = 0.0f;
  std::string stats_path;
  std::vector<std::string> aovs;
  bool quiet = false;
  // Node-emulator modes (replicated; svm and dataflow later).
  std::string node_memory = "4MiB";
  std::string network = "none";
  double network_scale = 0;  ///< seconds per ray for ipsc2; 0 = calibrate
  std::string topology = "hypercube";
  std::string work_item = "3x3";
  double timeout_s = 0;
  double stall_timeout_s = 60;
  double schedule_window_us = 200;
  std::string mail_wakeups = "auto";
  std::string clock = "cpu";
  std::string work_requests = "ring";
  std::string work_grants = "item";
  std::string submaps = "square";
  // svm
  std::uint32_t page_size = 1024;
  std::string directory_order = "auto";  ///< auto, linear or bricked
  std::string cache;  ///< "" = all free memory, "N" pages or "P%" of the database
  // dataflow
  int subsample = 8;
  std::string partition = "balanced";
  std::uint32_t queue_capacity = 0;  ///< node mailbox slots; 0 = the mode's default
};

/// --cache: "N" pages or "P%" of the database's pages into params; throws UsageError.
void parse_cache(const std::string& text, svm::SvmParams& params) {
  if (text.empty()) return;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  const std::string rest(end ? end : "");
  if (end == text.c_str() || !(rest.empty() || rest == "%") || !std::isfinite(v))
    throw UsageError("--cache must be a page count (e.g. 200) or a percentage of the database (e.g. 10%), got '" +
                     text + "'");
  if (rest == "%") {
    if (!(v > 0 && v <= 100))
      throw UsageError("--cache percentage must be in (0, 100], got '" + text + "'");
    params.cache_fraction = v / 100.0;
  } else {
    if (!(v >= 1 && v <= 4294967295.0) || v != std::floor(v))
      throw UsageError("--cache must be a whole number of pages from 1 to 4294967295, or a percentage, got '" + text +
                       "'");
    params.cache_pages = std::uint32_t(v);
  }
}

/// --submaps and --subsample as the control-oriented modes' submap params.
nodes::SubmapParams submap_params(const RenderOptions& o) {
  nodes::SubmapParams p;
  p.rule = nodes::parse_submap_rule(o.submaps);  // CLI checked the name
  p.subsample = o.subsample;
  return p;
}

bool is_node_mode(const std::string& mode) { return mode == "replicated" || mode == "svm" || mode == "dataflow"; }

/// The emulated machine for the node modes, from the options. Throws UsageError.
nodes::MachineParams machine_params(const RenderOptions& o) {
  nodes::MachineParams m;
  m.nodes = std::uint32_t(o.nodes);
  try {
    m.node_memory = nodes::parse_bytes(o.node_memory);
    m.topology = nodes::parse_topology(o.topology);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--node-memory/--topology: ") + e.what());
  }
  try {
    m.clock = nodes::parse_compute_clock(o.clock);
    m.work_request_route = nodes::parse_work_request_route(o.work_requests);
    m.work_grant = nodes::parse_work_grant(o.work_grants);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--clock/--work-requests/--work-grants: ") + e.what());
  }
  m.network = nodes::make_network(o.network, o.network_scale,
                                  m.clock == nodes::ComputeClock::kModel ? &m.cost_model : nullptr);
  m.timeout_s = 0;  // --timeout is the process's watchdog (apps/watchdog.h), which the machine polls
  m.stall_timeout_s = o.stall_timeout_s;
  m.schedule_window_s = o.schedule_window_us * 1e-6;
  if (o.mail_wakeups != "auto") m.scheduled_mail = o.mail_wakeups == "scheduled";
  return m;
}

/// What a frame produced besides the RenderResult (node modes only).
struct FrameExtras {
  nlohmann::json nodes;  ///< the machine report ("nodes" in --stats), null for in-process modes
  core::Image node;      ///< --aov node
  core::Image pages;     ///< --aov pages (svm)
  nlohmann::json svm;    ///< the "svm" object of --stats
  core::Image region;    ///< --aov region (dataflow)
  nlohmann::json dataflow;  ///< the "dataflow" object of --stats
};

/// The machine report's keys that every node mode fills the same way.
void fill_work_stats(const std::vector<nodes::WorkStats>& work, const std::vector<core::RenderStats>& tracing,
                     const nodes::RunReport& run, int node_count, nlohmann::json& j) {
  nodes::WorkStats sum;
  for (const nodes::WorkStats& w : work) sum += w;
  double busy = 0;
  for (const nodes::NodeReport& n : run.nodes) busy += n.counters.busy_s;
  j["work_s"] = busy;
  // Without a one-node run, T_1 is estimated by the summed busy time.
  j["efficiency_estimate"] = run.parallel_time_s > 0 ? busy / (double(node_count) * run.parallel_time_s) : 0.0;
  j["work"] = {{"items_own", sum.items_own},         {"items_received", sum.items_received},
               {"requests_sent", sum.requests_sent}, {"requests_forwarded", sum.requests_forwarded},
               {"grants", sum.grants_given},         {"pixels_granted", sum.pixels_granted},
               {"request_hops", sum.request_hops}};
  for (std::size_t i = 0; i < work.size() && i < j["per_node"].size(); ++i) {
    auto& e = j["per_node"][i];
    e["pixels"] = work[i].pixels;
    e["grants_given"] = work[i].grants_given;
    e["items_received"] = work[i].items_received;
    e["rays"] = tracing[i].rays.total();
  }
}

/// out.png -> out.depth.exr (same directory).
std::string aov_path(const std::string& output, const std::string& aov) {
  std::filesystem::path p(output);
  p.replace_extension();
  return p.string() + "." + aov + ".exr";
}

/// The host's acceleration structure: exactly one of the two is built.
struct Accelerator {
  std::optional<core::Grid> grid;             ///< --accel grid
  std::unique_ptr<core::EmbreeScene> embree;  ///< --accel embree
  std::optional<core::CellBlocks> blocks;     ///< the grid's packed cells (in-process modes, --pack-cells)
  double build_s = 0;                         ///< wall seconds to build it
};

/// Builds --accel's structure for `o`; the grid's packed cells only for the
/// in-process modes (the node modes trace the paper's per-primitive lists).
Accelerator build_accelerator(const RenderOptions& o, const core::Database& db) {
  Accelerator a;
  const auto t0 = std::chrono::steady_clock::now();
  core::GridParams gp;
  gp.skip_empty = o.skip_empty;
  gp.kind = grid_kind_for(o.grid);
  if (o.accel == "embree") {
    a.embree = std::make_unique<core::EmbreeScene>(db);
  } else {
    a.grid = core::build_grid(db, gp);
    if (o.pack_min > 0 && !is_node_mode(o.mode)) a.blocks = core::build_cell_blocks(db, *a.grid, o.pack_min);
  }
  a.build_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return a;
}

/// The one mode dispatch: renders `db` through `accel` in mode `o.mode`
/// with `params` (its mode field is set here). Every mode returns the same
/// RenderResult (colour, AOVs, counters summed over threads or nodes).
/// sequential and shared run core::render_image in this process; the node
/// modes (replicated, svm, dataflow: --nodes N) get one branch each here.
/// Throws UsageError for a mode/--nodes combination that makes no sense.
core::RenderResult render_frame(const RenderOptions& o, const core::Database& db, const Accelerator& accel,
                                core::RenderParams params, bool node_aov, bool pages_aov, FrameExtras& extras) {
  if (is_node_mode(o.mode) && accel.embree)
    throw UsageError("--accel embree is for the in-process modes; --mode " + o.mode + " traces with the grid");
  if (node_aov && !is_node_mode(o.mode))
    throw UsageError("--aov node needs a node-emulator mode (--mode replicated, svm or dataflow), not --mode " +
                     o.mode);
  if (pages_aov && o.mode != "svm") throw UsageError("--aov pages needs --mode svm");
  const bool region_aov = std::find(o.aovs.begin(), o.aovs.end(), "region") != o.aovs.end();
  if (region_aov && o.mode != "dataflow") throw UsageError("--aov region needs --mode dataflow");
  if (o.pack_given && o.pack_min > 0 && (o.mode == "replicated" || o.mode == "dataflow"))
    throw UsageError("--pack-cells " + std::to_string(o.pack_min) + " is for --mode sequential, shared or svm; --mode " +
                     o.mode + " walks the paper's object lists (leave --pack-cells out)");
  if (o.mode == "dataflow") {
    dataflow::DataflowParams dp;
    dp.render = params;
    dp.machine = machine_params(o);
    dp.machine.mailbox_capacity = o.queue_capacity;
    dp.subsample = o.subsample;
    dp.partition = dataflow::parse_partition(o.partition);
    dp.region_aov = region_aov || node_aov;
    dp.grid.kind = grid_kind_for(o.grid);  // each region's local grid: --grid's kind, as the host's
    dataflow::DataflowResult r = dataflow::render_dataflow(db, *accel.grid, dp);
    extras.nodes = r.run.to_json(true);
    double busy = 0;
    for (const nodes::NodeReport& n : r.run.nodes) busy += n.counters.busy_s;
    extras.nodes["work_s"] = busy;
    extras.nodes["efficiency_estimate"] =
        r.run.parallel_time_s > 0 ? busy / (double(o.nodes) * r.run.parallel_time_s) : 0.0;
    extras.dataflow = r.to_json();
    if (node_aov) extras.node = r.region;  // region i belongs to node i
    if (region_aov) extras.region = std::move(r.region);
    if (params.progress) params.progress->store(std::uint64_t(r.render.color.width) * r.render.color.height);
    return std::move(r.render);
  }
  if (o.mode == "replicated") {
    nodes::ReplicatedParams rp;
    rp.render = params;
    rp.machine = machine_params(o);
    std::tie(rp.item_w, rp.item_h) = parse_work_item(o.work_item);
    rp.submaps = submap_params(o);
    rp.node_aov = node_aov;
    nodes::ReplicatedResult r = nodes::render_replicated(db, *accel.grid, rp);
    extras.nodes = r.run.to_json(true);
    extras.nodes["submaps"] = r.submaps.to_json();
    extras.nodes["database_bytes_per_node"] = r.database_bytes;
    fill_work_stats(r.work, r.tracing, r.run, o.nodes, extras.nodes);
    extras.node = std::move(r.node);
    if (params.progress) params.progress->store(std::uint64_t(r.render.color.width) * r.render.color.height);
    return std::move(r.render);
  }
  if (o.mode == "svm") {
    svm::SvmParams sp;
    sp.render = params;
    sp.machine = machine_params(o);
    std::tie(sp.item_w, sp.item_h) = parse_work_item(o.work_item);
    sp.page_size = o.page_size;
    try {
      sp.directory_order = svm::parse_directory_order(o.directory_order);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--directory-order: ") + e.what());
    }
    sp.pack_min = o.pack_given ? o.pack_min : 0;  // svm pages the paper's object lists unless asked
    parse_cache(o.cache, sp);
    sp.submaps = submap_params(o);
    sp.node_aov = node_aov;
    sp.pages_aov = pages_aov;
    svm::SvmResult r = svm::render_svm(db, *accel.grid, sp);
    extras.nodes = r.run.to_json(true);
    extras.nodes["submaps"] = r.submaps.to_json();
    fill_work_stats(r.work, r.tracing, r.run, o.nodes, extras.nodes);
    extras.svm = r.to_json();
    extras.node = std::move(r.node);
    extras.pages = std::move(r.pages);
    if (params.progress) params.progress->store(std::uint64_t(r.render.color.width) * r.render.color.height);
    return std::move(r.render);
  }
  if (o.mode == "sequential" || o.mode == "shared") {
    if (o.nodes != 1)
      throw UsageError(fmt::format("--nodes {} needs a node-emulator mode; --mode {} runs in this process",
                                   o.nodes, o.mode));
    params.mode = core::parse_render_mode(o.mode);
    if (accel.embree) return core::render_image(core::EmbreeView(db, *accel.embree), db, params);
    return core::render_image(core::DirectView(db, *accel.grid, accel.blocks ? &*accel.blocks : nullptr), db,
                              params);
  }
  throw UsageError("unknown render mode '" + o.mode + "'");
}

void run_render(const RenderOptions& o) {
  core::RenderParams params;
  params.width = o.width;
  params.height = o.height;
  params.spp = o.spp;
  params.max_depth = o.max_depth;
  params.min_weight = o.min_weight;
  bool node_aov = false, pages_aov = false;
  for (const std::string& a : o.aovs) {
    if (a == "node") node_aov = true;
    else if (a == "pages") pages_aov = true;
    else if (a == "region") continue;  // dataflow: render_frame reads it from the options
    else if (a == "depth") params.depth_aov = true;
    else if (a == "normal") params.normal_aov = true;
    else if (a == "primitive") params.primitive_aov = true;
    else throw UsageError("unknown AOV '" + a + "' (supported: depth, normal, primitive, node, pages, region)");
  }
  if (!imageio::is_float_format(o.output) && std::filesystem::path(o.output).extension().empty())
    throw UsageError("output '" + o.output + "' has no extension to choose the image format");
  if (!imageio::can_write_format(o.output))
    throw UsageError("no image writer for the extension of '" + o.output + "' (try .png, .exr, .tif, .ppm)");
  if (o.grid.given && o.accel == "embree") throw UsageError("--grid is for --accel grid; --accel embree builds no grid");
  // Every output is declared, checked and given its temporary before any
  // work; the AOVs' files are those the options can produce.
  OutputFiles files(core::is_scene_file(o.source.spec) ? std::vector<std::string>{o.source.spec}
                                                       : std::vector<std::string>{});
  const std::size_t image_out = files.add(o.output, "image", false);
  const std::size_t stats_out = o.stats_path.empty() ? 0 : files.add(o.stats_path, "--stats file", true);
  std::map<std::string, std::size_t> aov_out, map_out;  // AOV name -> output
  for (const std::string& a : o.aovs) {
    if (aov_out.count(a)) continue;
    aov_out[a] = files.add(aov_path(o.output, a), "AOV", false);
    if (a == "node" || a == "pages")  // NAME.node.png, NAME.pages.png beside the EXR
      map_out[a] =
          files.add(std::filesystem::path(aov_path(o.output, a)).replace_extension(".png").string(), "AOV map", false);
  }

  const core::Scene scene = core::load_scene(o.source);
  const core::Database db = core::make_database(scene);
  if (db.primitives.empty()) {
    const std::size_t dropped = scene.dropped_degenerate + db.dropped_degenerate_triangles;
    throw std::runtime_error(fmt::format("{}: the scene has no primitives to render{}", o.source.spec,
                                         dropped == 0 ? std::string()
                                                      : fmt::format(" ({} degenerate polygon{} dropped)", dropped,
                                                                    dropped == 1 ? "" : "s")));
  }
  const Accelerator accel = build_accelerator(o, db);

  const core::View cam_view = [&] {
    try {
      return core::render_view(db);
    } catch (const std::runtime_error& e) {  // no view and bounds beyond float: name the scene
      throw std::runtime_error(o.source.spec + ": " + e.what());
    }
  }();
  // --width or --height alone: the other side keeps the view's aspect ratio.
  core::fit_resolution(params.width, params.height, cam_view);
  const std::uint64_t pixels = std::uint64_t(params.width > 0 ? params.width : cam_view.width) *
                               std::uint64_t(params.height > 0 ? params.height : cam_view.height);
  std::atomic<std::uint64_t> done{0};
  params.progress = &done;

  const auto t0 = std::chrono::steady_clock::now();
  const std::clock_t c0 = std::clock();
  ProgressLine progress("render", done, pixels, !o.quiet);
  FrameExtras extras;
  const core::RenderResult result = render_frame(o, db, accel, params, node_aov, pages_aov, extras);
  const double cpu_s = double(std::clock() - c0) / CLOCKS_PER_SEC;
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  progress.finish();

  std::vector<std::pair<std::string, std::string>> aov_files;  // (aov, path)
  auto write_aov = [&](const char* name, const core::Image& image) {
    if (image.empty()) return;
    const std::size_t id = aov_out.at(name);
    aov_files.emplace_back(name, files.path(id));
    files.image(id, image);
  };
  files.image(image_out, result.color);
  write_aov("depth", result.depth);
  write_aov("normal", result.normal);
  write_aov("primitive", result.primitive);
  write_aov("node", extras.node);
  write_aov("pages", extras.pages);
  write_aov("region", extras.region);
  // Pictures of the node modes' maps beside their data: NAME.node.png, NAME.pages.png.
  auto write_map = [&](const char* name, const core::Image& picture) {
    if (picture.empty()) return;
    const std::size_t id = map_out.at(name);
    aov_files.emplace_back(std::string(name) + "_map", files.path(id));
    files.image(id, picture);
  };
  if (!extras.node.empty()) write_map("node", imageio::label_map(extras.node));
  if (!extras.pages.empty()) write_map("pages", imageio::heat_map(extras.pages));

  const core::RenderStats& s = result.stats;
  if (!o.stats_path.empty()) {
    const core::SceneCounts sc = scene.counts();
    const core::DatabaseCounts dc = db.counts();
    nlohmann::json j = {
        {"scene", o.source.spec},
        {"tessellate", o.source.tessellate},
        {"mode", o.mode},
        {"accel", o.accel},
        {"nodes", o.nodes},
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
          {"refracted_tir", s.rays.refracted_tir},
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
        {"empty_jumps", s.traversal.empty_jumps},
        {"mailbox_skips", s.traversal.mailbox_skips},
        {"time", {{"wall_s", wall_s}, {"cpu_s", cpu_s}, {"accel_build_s", accel.build_s}}},
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
        {"output", o.output},
    };
    if (accel.grid) {
      j["grid_resolution"] = {accel.grid->info.res[0], accel.grid->info.res[1], accel.grid->info.res[2]};
      j["grid"] = grid_json(*accel.grid);
      j["grid"]["build_s"] = accel.build_s;
      j["skip_empty"] = o.skip_empty;
      // svm packs its paged database, not the host's grid.
      const bool svm = !extras.svm.is_null();
      j["pack_cells"] = svm ? extras.svm["pack_cells"] : nlohmann::json(accel.blocks ? accel.blocks->min_triangles : 0);
      j["packed_blocks"] = svm ? extras.svm["packed_blocks"]
                               : nlohmann::json(accel.blocks ? accel.blocks->blocks.size() : 0);
    }
    for (const auto& [name, path] : aov_files) j["aov_outputs"][name] = path;
    if (!extras.nodes.is_null()) {
      // "nodes" stays the count; the machine's totals and each node's counters beside it.
      j["per_node"] = extras.nodes["per_node"];
      extras.nodes.erase("per_node");
      j["machine"] = extras.nodes;
    }
    if (!extras.svm.is_null()) {
      j["svm"] = extras.svm;
      j["svm"]["per_node"] = nullptr;
      j["svm"].erase("per_node");
      for (std::size_t i = 0; i < extras.svm["per_node"].size() && i < j["per_node"].size(); ++i)
        j["per_node"][i]["svm"] = extras.svm["per_node"][i];
    }
    if (!extras.dataflow.is_null()) j["dataflow"] = extras.dataflow;
    files.text(stats_out, j.dump(2) + "\n");
  }
  // The summary goes to stderr when stdout carries an output (--stats -).
  std::FILE* report = files.uses_stdout() ? stderr : stdout;
  files.commit();
  if (!o.quiet) {
    fmt::print(report, "{}: {}x{} spp {}x{} mode {} accel {} in {:.3f} s wall ({:.3f} s cpu)\n", o.output,
               result.color.width, result.color.height, params.spp, params.spp, o.mode, o.accel, wall_s, cpu_s);
    fmt::print(report, "rays: {} primary, {} shadow, {} reflected, {} refracted ({} total)\n", s.rays.primary,
               s.rays.shadow, s.rays.reflected, s.rays.refracted, s.rays.total());
    for (const std::string& line : node_run_summary(extras.nodes, extras.svm, extras.dataflow))
      fmt::print(report, "{}\n", line);
    for (const auto& [name, path] : aov_files) fmt::print(report, "{}: {}\n", name, path);
  }
}

}  // namespace

void register_render_command(CLI::App& app) {
  auto o = std::make_shared<RenderOptions>();
  CLI::App* c = app.add_subcommand("render", "Render a scene (Whitted ray tracing, SPD shading) to an image");
  c->footer(
      "Shading: ambient + per light a shadow ray, Lambert and Phong terms, mirror reflection weighted by Ks,\n"
      "refraction weighted by T (Snell, total internal reflection); light and ambient intensity sqrt(L)/(2L).\n"
      "Sequential and shared modes give bit-identical images. A progress line appears on stderr after 1 s\n"
      "when stderr is a terminal (not with --quiet).\n"
      "Exit status: 0 ok; 1 unreadable or malformed scene (file:line:col: message) or write error;\n"
      "2 bad option or value.\n"
      "Example: raynode render teapot:8 -o teapot.png --mode shared --aov depth,primitive --stats teapot.json");
  add_scene_options(*c, o->source);
  add_camera_options(*c, o->source.view);
  c->add_option("-o,--output", o->output,
                "Output image; format by extension: LDR (png, tif, ppm, jpg, ...) gets 8 bits clamped to [0,1], "
                "exr/hdr get linear floats")
      ->capture_default_str();
  c->add_option("--mode", o->mode,
                "sequential (one thread), shared (TBB threads over 16x16 tiles), replicated (--nodes emulated "
                "nodes, each with a full database copy in its --node-memory; pixels by submaps and work stealing), "
                "or svm (the paper's shared virtual memory: the database paged over the nodes' memories, LRU page "
                "caches, same pixel distribution), or dataflow (the paper's data-oriented algorithm: one region of "
                "equal estimated load per node, rays sent between region owners, spills to the host)")
      ->check(CLI::IsMember({"sequential", "shared", "replicated", "svm", "dataflow"}))
      ->capture_default_str();
  c->add_option("--nodes", o->nodes,
                "Emulated nodes (threads with private memories), for the node-emulator modes (replicated, svm, "
                "dataflow); sequential and shared need 1")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  c->add_option("--accel", o->accel,
                "Ray queries through the uniform grid (3D-DDA, the paper's tracer) or Embree 3 (same shading; pixels "
                "differ only where the two pick different primitives)")
      ->check(CLI::IsMember({"grid", "embree"}))
      ->capture_default_str();
  add_grid_option(*c, o->grid);
  add_skip_empty_option(*c, o->skip_empty);
  add_pack_cells_option(*c, o->pack_min);
  c->add_option("--width", o->width,
                "Image width in pixels (default: the scene's view; given alone, the height keeps the view's aspect "
                "ratio)")
      ->check(CLI::Range(1, 16384));
  c->add_option("--height", o->height,
                "Image height in pixels (default: the scene's view; given alone, the width keeps the view's aspect "
                "ratio)")
      ->check(CLI::Range(1, 16384));
  c->add_option("--spp", o->spp, "N: N x N stratified samples per pixel (fixed offsets, no randomness)")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  c->add_option("--max-depth", o->max_depth, "Ray levels, eye ray = 1 (SPD: 5)")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  c->add_option("--min-weight", o->min_weight,
                "Skip reflected/refracted rays whose weight (product of Ks, T along the path) is below this "
                "(0 = off)")
      ->check(finite_range(0, 1))
      ->capture_default_str();
  c->add_option("--stats", o->stats_path,
                "Write counters (rays per kind, skips per reason, intersection tests, cells) and timings as "
                "JSON to this file");
  c->add_option("--aov", o->aovs,
                "Extra float EXR outputs of the first hit of the ray through each pixel centre, comma-separated: "
                "depth (NAME.depth.exr: eye-to-hit distance in world units, +inf on a miss), normal "
                "(NAME.normal.exr: unit shading normal facing the eye, 0 on a miss), primitive "
                "(NAME.primitive.exr: file-order index of the NFF shape hit, counting p/pp/s/c statements "
                "from 0 after --tessellate, -1 on a miss), node (node modes: NAME.node.exr, id of the node that "
                "computed the pixel, and NAME.node.png, one colour per node, as in the paper's Figure 6), pages "
                "(svm: NAME.pages.exr, distinct pages touched per pixel, and NAME.pages.png, its heat map), region "
                "(dataflow: NAME.region.exr, the region of each primary hit, -1 on a miss)")
      ->delimiter(',')
      ->check(CLI::IsMember({"depth", "normal", "primitive", "node", "pages", "region"}));
  c->add_option("--page-size", o->page_size,
                "svm: bytes per page of the shared virtual memory, a power of two from 64 (the paper: 1024)")
      ->capture_default_str();
  c->add_option("--directory-order", o->directory_order, kDirectoryOrderHelp)
      ->check(CLI::IsMember({"auto", "linear", "bricked"}))
      ->capture_default_str();
  c->add_option("--cache", o->cache,
                "svm: page cache per node, N pages or P% of the database's pages (default: all the memory a node "
                "has left after its home pages, page table and mailbox)");
  c->add_option("--subsample", o->subsample,
                "dataflow, and replicated/svm with --submaps balanced: the load estimate traces one pixel per NxN "
                "block (8 = the paper's 1.5%); --aov region "
                "(NAME.region.exr) shows the region of each primary hit, -1 on a miss")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  c->add_option("--partition", o->partition,
                "dataflow: balanced (median cuts on the estimated load, the paper's method) or equal (equal-size "
                "regions, the paper's comparison)")
      ->check(CLI::IsMember({"balanced", "equal"}))
      ->capture_default_str();
  c->add_option("--queue-capacity", o->queue_capacity,
                "dataflow: slots of each node's mailbox (default 1024); a ray for a full mailbox goes to the host, "
                "which forwards it later (1 forces spills)")
      ->check(CLI::Range(1, 1 << 20));
  c->add_option("--node-memory", o->node_memory,
                "Node modes: memory budget per node (B, KiB, MiB, GiB; the iPSC/2 node had 4 MiB)")
      ->capture_default_str();
  c->add_option("--network", o->network,
                "Node modes: network cost model for virtual time: none (free), ipsc2 (the paper's iPSC/2 scaled to "
                "this machine's ray speed), cluster (1.5 us, 12.5 GB/s)")
      ->check(CLI::IsMember({"none", "ipsc2", "cluster"}))
      ->capture_default_str();
  c->add_option("--network-scale", o->network_scale,
                "ipsc2: this machine's seconds per ray (default: measured at start, ~0.1 s)")
      ->check(finite_positive());
  c->add_option("--topology", o->topology, "Node modes: interconnect: hypercube (iPSC/2), ring, torus")
      ->check(CLI::IsMember({"hypercube", "ring", "torus"}))
      ->capture_default_str();
  c->add_option("--work-item", o->work_item, "replicated, svm: pixels per work item, WxH")->capture_default_str();
  c->add_option("--work-requests", o->work_requests,
                "replicated, svm: where an idle node asks for work: ring (the paper: to its ring successor, on "
                "round the ring), last-grantor (first straight to the node that gave it its last item, then "
                "the ring: fewer hops) or off (no requests: each node renders its static submap and nothing "
                "else, the baseline that shows what the requests gain; which node renders which pixel no "
                "longer depends on thread scheduling)")
      ->check(CLI::IsMember({"ring", "last-grantor", "off"}))
      ->capture_default_str();
  c->add_option("--work-grants", o->work_grants,
                "replicated, svm: what a busy node grants a work request: item (the paper: one work item from "
                "the far end of its submap), nearest (one work item, the one nearest the requester's last, so "
                "that its items lie together) or half (the far half of its remaining item rows, or of its last "
                "row's items, as one rectangle that the requester renders as its new submap and grants from in "
                "turn: a requester's pixels stay together, so its cache and svm's pages serve more of them)")
      ->check(CLI::IsMember({"item", "nearest", "half"}))
      ->capture_default_str();
  c->add_option("--submaps", o->submaps,
                "replicated, svm: the nodes' static submaps: square (the paper: near-square parts of equal area) "
                "or balanced (parts of near-equal cost, estimated by tracing one pixel per --subsample block on "
                "the host first: fewer pixels move by work requests, so svm's nodes fault on fewer pages)")
      ->check(CLI::IsMember({"square", "balanced"}))
      ->capture_default_str();
  c->add_option("--schedule-window", o->schedule_window_us,
                "Node modes: virtual-time scheduling window in microseconds: a node this far ahead of a waiting "
                "one hands the CPU over (smaller = closer to a real parallel machine, more thread switches; "
                "negative = off, the OS schedules the node threads)")
      ->check(finite_range(-kNoBound, kNoBound))
      ->capture_default_str();
  c->add_option("--mail-wakeups", o->mail_wakeups, kMailWakeupsHelp)
      ->check(CLI::IsMember({"auto", "scheduled", "immediate"}))
      ->capture_default_str();
  c->add_option("--clock", o->clock,
                "Node modes: what advances a node's virtual clock while it computes: cpu (its thread's CPU time) "
                "or model (operation counts x calibrated unit costs: repeatable, free of the host's thread "
                "switches; see `raynode bench cost-model`)")
      ->check(CLI::IsMember({"cpu", "model"}))
      ->capture_default_str();
  c->add_option("--stall-timeout", o->stall_timeout_s,
                "Node modes: stop with an error naming what each node waits for when no message was sent for "
                "this many wall seconds (0 = never)")
      ->check(finite_range(0, 1e9))
      ->capture_default_str();
  c->add_option("--timeout", o->timeout_s,
                "Stop with an error (exit 1, no file written) after this many wall seconds (0 = never); in the node "
                "modes the message names what each node waits for")
      ->check(finite_range(0, kNoBound));
  c->add_flag("--quiet,-q", o->quiet, "Print nothing on success, no progress line");
  c->callback([o, c] {
    o->pack_given = c->get_option("--pack-cells")->count() > 0;
    // No option is ignored without a word: one that this mode does not read is a usage error.
    check_mode_options(*c, {o->mode});
    start_timeout_watchdog(o->timeout_s);  // from process start, over every step
    run_render(*o);
  });
}

}  // namespace raynode::apps
