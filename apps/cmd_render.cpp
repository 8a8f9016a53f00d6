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
#include "apps/run_info.h"
#include "apps/node_runs.h"
#include "apps/output_files.h"
#include "apps/progress.h"
#include "apps/render_stats.h"
#include "apps/run_summary.h"
#include "apps/transports.h"
#include "apps/watchdog.h"
#include "core/database.h"
#include "core/embree_scene.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/scene_source.h"
#include "modes/modes.h"
#include "imageio/false_color.h"
#include "imageio/write_image.h"
#include "nodes/machine.h"
#include "nodes/network.h"

namespace raynode::apps {

namespace {

struct RenderOptions {
  core::SceneSource source = tracing_source();
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
  std::string shadow_rays = "facing";
  std::string stats_path;
  std::vector<std::string> aovs;
  bool quiet = false;
  double timeout_s = 0;  ///< --timeout: the process's watchdog (apps/watchdog.h)
  std::string transport = "local";  ///< --transport: local (the emulator) or mpi (apps/transports.h)
  std::string page_fetch = "request";  ///< --page-fetch: svm's page faults by request and reply, or one-sided get
  bool nodes_given = false;         ///< --nodes was on the command line
  nodes::Transport* transport_impl = nullptr;  ///< set by run_render under --transport mpi
  /// The emulated machine and the node modes: the options every node-mode
  /// command declares once (add_node_run_options); in-process modes refuse them.
  NodeRunOptions run;
};

/// The node modes' spec from the options (the network calibrated here, once),
/// with the machine's node count and --timeout left to the process's
/// watchdog, which the machine polls. Throws UsageError.
NodeRunSpec node_spec(const RenderOptions& o) {
  NodeRunSpec spec = make_node_run_spec(o.run);
  spec.machine.nodes = std::uint32_t(o.nodes);
  spec.machine.timeout_s = 0;
  spec.machine.transport = o.transport_impl;
  return spec;
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

/// The least triangle count of a packed cell in `o`'s node modes: svm
/// pages the paper's object lists (0) unless --pack-cells was given.
std::uint32_t node_pack_min(const RenderOptions& o) { return o.pack_given ? o.pack_min : 0; }

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
    // The grid for the cells the tracer packs: the in-process modes'
    // (--pack-cells, on by default), the node modes' node_pack_min.
    const bool node_mode = modes::is_node_mode(modes::parse_mode(o.mode));
    a.grid = core::build_grid(db, core::grid_params_for_packed_cells(gp, node_mode ? node_pack_min(o) : o.pack_min));
    if (o.pack_min > 0 && !node_mode)
      a.blocks = core::build_cell_blocks(db, *a.grid, o.pack_min, core::PackKinds::kTrianglesAndSpheres);
  }
  a.build_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return a;
}

/// The request for `o`'s mode (modes/modes.h) with `params`, after the
/// checks that name the options: throws UsageError for a mode and option
/// combination that makes no sense.
modes::RunRequest render_request(const RenderOptions& o, const Accelerator& accel, const core::RenderParams& params,
                                 bool node_aov, bool pages_aov) {
  modes::RunRequest req;
  try {
    req.mode = modes::parse_mode(o.mode);
  } catch (const std::invalid_argument&) {
    throw UsageError("unknown render mode '" + o.mode + "'");
  }
  const bool node_mode = modes::is_node_mode(req.mode);
  if (node_mode && accel.embree)
    throw UsageError("--accel embree is for the in-process modes; --mode " + o.mode + " traces with the grid");
  if (node_aov && !node_mode)
    throw UsageError("--aov node needs a node-emulator mode (--mode replicated, svm or dataflow), not --mode " +
                     o.mode);
  if (pages_aov && o.mode != "svm") throw UsageError("--aov pages needs --mode svm");
  req.region_aov = std::find(o.aovs.begin(), o.aovs.end(), "region") != o.aovs.end();
  if (req.region_aov && o.mode != "dataflow") throw UsageError("--aov region needs --mode dataflow");
  if (o.pack_given && o.pack_min > 0 && (o.mode == "replicated" || o.mode == "dataflow"))
    throw UsageError("--pack-cells " + std::to_string(o.pack_min) + " is for --mode sequential, shared or svm; --mode " +
                     o.mode + " walks the paper's object lists (leave --pack-cells out)");
  if (!node_mode && o.nodes != 1)
    throw UsageError(fmt::format("--nodes {} needs a node-emulator mode; --mode {} runs in this process", o.nodes,
                                 o.mode));
  req.render = params;
  req.node_aov = node_aov;
  req.pages_aov = pages_aov;
  req.embree = accel.embree.get();
  req.blocks = accel.blocks ? &*accel.blocks : nullptr;
  if (node_mode) {
    req.nodes = node_spec(o);
    req.nodes.pack_min = node_pack_min(o);
    if (o.page_fetch == "get" && o.transport != "mpi")
      throw UsageError("--page-fetch get reads home pages one-sidedly over MPI: it needs --transport mpi");
    req.nodes.fetch_by_get = o.page_fetch == "get";
  }
  return req;
}

/// Renders `db` through `accel` in mode `o.mode` with `params`
/// (modes::render), and fills `extras` with the node modes' AOVs and
/// --stats objects. Throws UsageError for a mode/option combination that
/// makes no sense.
core::RenderResult render_frame(const RenderOptions& o, const core::Database& db, const Accelerator& accel,
                                const core::RenderParams& params, bool node_aov, bool pages_aov, FrameExtras& extras) {
  modes::RunRequest req = render_request(o, accel, params, node_aov, pages_aov);
  // The model clock checked on this scene (--calibrate), before the run.
  if (modes::is_node_mode(req.mode) && accel.grid)
    extras.calibration = calibrate_model_clock(req.nodes.machine, params, db, *accel.grid, o.run.calibrate);
  modes::RunResult r = [&] {
    try {
      return modes::render(db, accel.grid ? &*accel.grid : nullptr, req);
    } catch (const std::invalid_argument& e) {
      if (modes::is_node_mode(req.mode)) throw;  // a node mode's parameters: its message names them
      throw UsageError(e.what());
    }
  }();
  node_mode_json(r, o.nodes, extras);
  if (extras.calibration.measured) extras.nodes["model_calibration"] = extras.calibration.to_json();
  extras.node = std::move(r.node);
  extras.pages = std::move(r.pages);
  extras.region = std::move(r.region);
  return std::move(r.render);
}

/// The render's parameters from `o`, and which of the node modes' AOVs it
/// asks for. Throws UsageError for an unknown AOV.
core::RenderParams render_params(const RenderOptions& o, bool& node_aov, bool& pages_aov) {
  core::RenderParams params;
  params.width = o.width;
  params.height = o.height;
  params.spp = o.spp;
  params.max_depth = o.max_depth;
  params.min_weight = o.min_weight;
  params.shadow_rays = shadow_rays_from_name(o.shadow_rays);
  node_aov = pages_aov = false;
  for (const std::string& a : o.aovs) {
    if (a == "node") node_aov = true;
    else if (a == "pages") pages_aov = true;
    else if (a == "region") continue;  // dataflow: render_request reads it from the options
    else if (a == "depth") params.depth_aov = true;
    else if (a == "normal") params.normal_aov = true;
    else if (a == "primitive") params.primitive_aov = true;
    else throw UsageError("unknown AOV '" + a + "' (supported: depth, normal, primitive, node, pages, region)");
  }
  return params;
}

/// Every file a render writes, declared, checked and given its temporary
/// before any work (OutputFiles): the image, --stats, and each AOV the
/// options can produce (NAME.AOV.exr; NAME.node.png, NAME.pages.png beside
/// the node modes' maps). Throws UsageError for an output it cannot write.
class RenderOutputs {
 public:
  explicit RenderOutputs(const RenderOptions& o)
      : files_(core::is_scene_file(o.source.spec) ? std::vector<std::string>{o.source.spec}
                                                  : std::vector<std::string>{}) {
    if (!imageio::is_float_format(o.output) && std::filesystem::path(o.output).extension().empty())
      throw UsageError("output '" + o.output + "' has no extension to choose the image format");
    if (!imageio::can_write_format(o.output))
      throw UsageError("no image writer for the extension of '" + o.output + "' (try .png, .exr, .tif, .ppm)");
    image_ = files_.add(o.output, "image", false);
    if (!o.stats_path.empty()) stats_ = files_.add(o.stats_path, "--stats file", true);
    for (const std::string& a : o.aovs) {
      if (aov_.count(a)) continue;
      aov_[a] = files_.add(aov_path(o.output, a), "AOV", false);
      if (a == "node" || a == "pages")
        map_[a] = files_.add(std::filesystem::path(aov_path(o.output, a)).replace_extension(".png").string(),
                             "AOV map", false);
    }
  }

  /// Stages the image and the AOVs there are (names and paths in aov_files()).
  void images(const core::RenderResult& result, const FrameExtras& extras) {
    files_.image(image_, result.color);
    aov("depth", result.depth);
    aov("normal", result.normal);
    aov("primitive", result.primitive);
    aov("node", extras.node);
    aov("pages", extras.pages);
    aov("region", extras.region);
    if (!extras.node.empty()) map("node", imageio::label_map(extras.node));
    if (!extras.pages.empty()) map("pages", imageio::heat_map(extras.pages));
  }
  /// Stages the --stats document, if asked for.
  void stats(const nlohmann::json& j) {
    if (stats_) files_.text(*stats_, j.dump(2) + "\n");
  }
  bool wants_stats() const { return stats_.has_value(); }
  /// Replaces every output with its staged file (OutputFiles::commit).
  void commit() { files_.commit(); }
  /// Where the summary goes: stderr when stdout carries an output (--stats -).
  std::FILE* report() const { return files_.uses_stdout() ? stderr : stdout; }
  const std::vector<std::pair<std::string, std::string>>& aov_files() const { return aov_files_; }

 private:
  void aov(const char* name, const core::Image& image) {
    if (image.empty()) return;
    const std::size_t id = aov_.at(name);
    aov_files_.emplace_back(name, files_.path(id));
    files_.image(id, image);
  }
  void map(const char* name, const core::Image& picture) {
    const std::size_t id = map_.at(name);
    aov_files_.emplace_back(std::string(name) + "_map", files_.path(id));
    files_.image(id, picture);
  }

  OutputFiles files_;
  std::size_t image_ = 0;
  std::optional<std::size_t> stats_;
  std::map<std::string, std::size_t> aov_, map_;  // AOV name -> output
  std::vector<std::pair<std::string, std::string>> aov_files_;  // (aov, path) staged
};

/// `o`'s scene and its database; throws std::runtime_error naming the scene
/// when nothing is left to render.
std::pair<core::Scene, core::Database> load_database(const RenderOptions& o) {
  core::Scene scene = core::load_scene(o.source);
  core::Database db = core::make_database(scene);
  if (db.primitives.empty()) {
    const std::size_t dropped = scene.dropped_degenerate + db.dropped_degenerate_triangles;
    throw std::runtime_error(fmt::format("{}: the scene has no primitives to render{}", o.source.spec,
                                         dropped == 0 ? std::string()
                                                      : fmt::format(" ({} degenerate polygon{} dropped)", dropped,
                                                                    dropped == 1 ? "" : "s")));
  }
  return {std::move(scene), std::move(db)};
}

/// The image's pixel count for `params` over `db`'s view; fits a lone
/// --width or --height to the view's aspect ratio.
std::uint64_t frame_pixels(const RenderOptions& o, const core::Database& db, core::RenderParams& params) {
  const core::View cam_view = [&] {
    try {
      return core::render_view(db);
    } catch (const std::runtime_error& e) {  // no view and bounds beyond float: name the scene
      throw std::runtime_error(o.source.spec + ": " + e.what());
    }
  }();
  core::fit_resolution(params.width, params.height, cam_view);
  return std::uint64_t(params.width > 0 ? params.width : cam_view.width) *
         std::uint64_t(params.height > 0 ? params.height : cam_view.height);
}

/// Under --transport mpi: starts MPI, takes the node count from the ranks
/// and records the transport in `o`. Throws UsageError for a --nodes other
/// than the ranks.
std::unique_ptr<nodes::Transport> open_transport(RenderOptions& o) {
  std::unique_ptr<nodes::Transport> t = make_transport(o.transport);
  if (!t) return t;
  const int ranks = int(t->processes());
  if (o.nodes_given && o.nodes != ranks)
    throw UsageError(fmt::format("--nodes {} under --transport mpi: the MPI job has {} ranks, one node each (leave "
                                 "--nodes out, or mpirun -np {})",
                                 o.nodes, ranks, o.nodes));
  o.nodes = ranks;
  o.transport_impl = t.get();
  return t;
}

void run_render(RenderOptions& o) {
  bool node_aov = false, pages_aov = false;
  core::RenderParams params = render_params(o, node_aov, pages_aov);
  if (o.grid.given && o.accel == "embree") throw UsageError("--grid is for --accel grid; --accel embree builds no grid");
  const std::unique_ptr<nodes::Transport> transport = open_transport(o);
  // Under MPI only rank 0, the host's, writes and reports; the others run their node.
  const bool writer = !transport || transport->process() == 0;
  if (!writer) o.quiet = true;
  std::optional<RenderOutputs> outputs;
  if (writer) outputs.emplace(o);
  const auto [scene, db] = load_database(o);
  const Accelerator accel = build_accelerator(o, db);
  const std::uint64_t pixels = frame_pixels(o, db, params);
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
  if (!outputs) return;

  outputs->images(result, extras);
  if (outputs->wants_stats())
    outputs->stats(render_stats_json(RenderRecord{
        o.source.spec, o.source.tessellate, o.source.floor, o.mode, o.accel, o.output, o.nodes, params, result,
        wall_s, cpu_s, scene, db, accel.grid ? &*accel.grid : nullptr, accel.blocks ? &*accel.blocks : nullptr, accel.build_s,
        o.skip_empty, extras, outputs->aov_files()}));
  std::FILE* report = outputs->report();  // before commit, which releases the outputs
  outputs->commit();
  if (o.quiet) return;
  const core::RenderStats& s = result.stats;
  fmt::print(report, "{}: {}x{} spp {}x{} mode {} accel {} in {:.3f} s wall ({:.3f} s cpu)\n", o.output,
             result.color.width, result.color.height, params.spp, params.spp, o.mode, o.accel, wall_s, cpu_s);
  fmt::print(report, "rays: {} primary, {} shadow, {} reflected, {} refracted ({} total)\n", s.rays.primary,
             s.rays.shadow, s.rays.reflected, s.rays.refracted, s.rays.total());
  for (const std::string& line : node_run_summary(extras.nodes, extras.svm, extras.dataflow))
    fmt::print(report, "{}\n", line);
  if (extras.calibration.measured) fmt::print(report, "{}\n", extras.calibration.summary());
  for (const auto& [name, path] : outputs->aov_files()) fmt::print(report, "{}: {}\n", name, path);
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
                "dataflow); sequential and shared need 1. N > 1 without --mode renders with svm")
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
  add_shadow_rays_option(*c, o->shadow_rays);
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
  add_node_run_options(*c, o->run, {.experiment = false, .page_size = true, .cache = true, .dataflow = true});
  c->add_option("--timeout", o->timeout_s,
                "Stop with an error (exit 1, no file written) after this many wall seconds (0 = never); in the node "
                "modes the message names what each node waits for")
      ->check(finite_range(0, kNoBound));
  c->add_flag("--quiet,-q", o->quiet, "Print nothing on success, no progress line");
  c->add_option("--transport", o->transport,
                std::string("Where the node modes' participants run: local (the emulator: every node a thread of this "
                            "process) or mpi (under mpirun -np N: node r on MPI rank r, the host a thread of rank 0, "
                            "N nodes; only rank 0 writes files)") +
                    (have_mpi_transport() ? "" : "; this build has no MPI"))
      ->check(CLI::IsMember({"local", "mpi"}))
      ->capture_default_str();
  c->add_option("--page-fetch", o->page_fetch,
                "svm: how a page fault gets its page: request (the paper's: a message to the home node, which "
                "answers it) or get (--transport mpi: a one-sided MPI_Get of the home node's frame; the home node "
                "takes no part, and no page messages are counted)")
      ->check(CLI::IsMember({"request", "get"}))
      ->capture_default_str();
  c->callback([o, c] {
    o->pack_given = c->get_option("--pack-cells")->count() > 0;
    o->nodes_given = c->get_option("--nodes")->count() > 0;
    // `render SCENE --nodes=N` is how users are told to render on N nodes:
    // without --mode it runs the paper's main algorithm; so does an MPI job.
    if ((o->nodes > 1 || o->transport == "mpi") && c->get_option("--mode")->count() == 0) {
      o->mode = "svm";
      if (!o->quiet && o->transport != "mpi")
        fmt::print(stderr, "raynode: --nodes {} without --mode: rendering with svm, the paper's shared virtual memory "
                           "algorithm (--mode replicated or dataflow picks another)\n",
                   o->nodes);
    }
    // No option is ignored without a word: one that this mode does not read is a usage error.
    check_mode_options(*c, {o->mode});
    start_timeout_watchdog(o->timeout_s);  // from process start, over every step
    run_render(*o);
  });
}

}  // namespace raynode::apps
