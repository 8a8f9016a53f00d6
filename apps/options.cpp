// The options several subcommands share (commands.h): the scene, the camera, the grid
// kind, the grid walk's empty-space jumps, packed cells, and the check that no option is
// given to a mode that ignores it.
#include <fmt/core.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <vector>

#include "apps/commands.h"
#include "core/cell_blocks.h"
#include "core/mesh_file.h"

namespace raynode::apps {

namespace {

/// The number `text` spells, whole (strtod: "nan" and "inf" included);
/// false if it is not one.
bool parse_double(const std::string& text, double& v) {
  char* end = nullptr;
  v = std::strtod(text.c_str(), &end);
  return end != text.c_str() && *end == '\0';
}

}  // namespace

void add_scene_options(CLI::App& cmd, core::SceneSource& source) {
  cmd.add_option("scene", source.spec,
                 "NFF file (.nff, .nff.gz), mesh file (.obj, .ply, .stl, .off, .gltf, .glb, ...: docs/meshes.md) or "
                 "built-in SPD scene name[:size]: teapot, mount, rings, tetra, balls, gears, tree, lattice, shells, "
                 "jacks, sombrero (e.g. teapot:8, mount:6, tetra:9)")
      ->required();
  cmd.add_option("--tessellate,-t", source.tessellate,
                 "Replace spheres by 12*R^2 and cones by 8*R triangles, as SPD's -t R (0 = curved)")
      ->check(CLI::Range(0, 1000));
  cmd.add_option("--scale", source.transform.scale,
                 "Scale the whole scene (geometry, lights, view) by S about the origin, after tessellation; the "
                 "picture should not change [default: 1]")
      ->check(CLI::PositiveNumber);
  cmd.add_option_function<std::vector<double>>(
         "--translate",
         [&source](const std::vector<double>& v) { source.transform.translate = {v[0], v[1], v[2]}; },
         "Move the whole scene by X,Y,Z world units (after --scale) [default: 0,0,0]")
      ->delimiter(',')
      ->expected(3);
  add_floor_option(cmd, source.floor);
}

void add_floor_option(CLI::App& cmd, double& floor) {
  cmd.add_option("--floor", floor,
                 "Add a square floor K times the scene's width under it, along the view's up (a stadium "
                 "variant: a small object in a huge scene), before --scale and --translate [default: none]")
      ->check(CLI::Range(1.0, 1e6));
}

void add_camera_options(CLI::App& cmd, core::ViewOverride& view) {
  auto point = [&cmd](const char* name, std::optional<core::Vec3>& field, const char* help) {
    cmd.add_option_function<std::vector<double>>(
           name, [&field](const std::vector<double>& v) { field = core::Vec3{float(v[0]), float(v[1]), float(v[2])}; },
           help)
        ->delimiter(',')
        ->expected(3)
        ->type_name("X,Y,Z")
        ->check(finite_range(-3.0e38, 3.0e38));
  };
  point("--eye", view.eye, "Camera position (the view's 'from'), scene file units [default: the scene's view]");
  point("--at", view.at, "Point the camera looks at [default: the scene's view]");
  point("--up", view.up, "Camera up direction, not parallel to --at minus --eye [default: the scene's view]");
  cmd.add_option_function<double>(
         "--fov", [&view](double v) { view.fov = float(v); },
         "Full horizontal field of view in degrees, NFF's 'angle', in (0, 180) [default: the scene's view]")
      ->type_name("DEG")
      ->check(CLI::Validator(
          [](std::string& text) -> std::string {
            double v = 0;
            if (!parse_double(text, v) || !std::isfinite(v) || !(v > 0.0 && v < 180.0))
              return fmt::format("must be a field of view in (0, 180) degrees, got '{}'", text);
            return {};
          },
          "DEG in (0, 180)"));
}

CLI::Option* add_json_option(CLI::App& cmd, std::string& path, const std::string& what) {
  return cmd
      .add_option_function<std::string>(
          "--json",
          [&path](const std::string& file) {
            path = file.empty() ? "-" : file;
            const std::string lower = [&] {
              std::string s = path;
              for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
              return s;
            }();
            if (lower.ends_with(".nff") || lower.ends_with(".gz") || core::is_mesh_extension(lower))
              throw CLI::ValidationError("--json", "'" + path +
                                                       "' is a scene file, not a JSON file to write (--json "
                                                       "alone goes before or after the scenes; --json=FILE names the "
                                                       "file)");
          },
          what + " as JSON: to stdout with --json alone (or -), else to FILE")
      ->expected(0, 1)
      ->type_name("[FILE]");
}

void add_skip_empty_option(CLI::App& cmd, bool& skip_empty) {
  cmd.add_option_function<std::string>(
         "--skip-empty", [&skip_empty](const std::string& v) { skip_empty = v == "on"; },
         "Grid walk: on = jump over empty space (Chebyshev distances kept in empty cells); off = step cell by "
         "cell, as the paper's tracer (same hits, more cells visited) [default: on]")
      ->check(CLI::IsMember({"on", "off"}));
}

void add_grid_density_option(CLI::App& cmd, float& density) {
  cmd.add_option("--grid-density", density,
                 "Grid cells per primitive: the uniform grid's, and the adaptive grid's at every level (its top grid "
                 "and each sub-grid)")
      ->check(finite_range(0.01, 1000));
}

void set_grid_density(core::GridParams& params, float density) {
  params.density = density;
  params.top_density = density;
}

void add_grid_option(CLI::App& cmd, GridChoice& choice) {
  cmd.add_option_function<std::string>(
         "--grid",
         [&choice](const std::string& v) {
           choice.given = v == "uniform" ? core::GridKind::kUniform : core::GridKind::kAdaptive;
         },
         "Grid: adaptive = a coarse top grid whose dense cells hold their own sub-grids (Jevans & Wyvill 1989; "
         "Kalojanov et al. 2011); uniform = one resolution for the whole scene, the paper's; in dataflow mode, the "
         "kind of each region's local grid [default: adaptive]")
      ->check(CLI::IsMember({"adaptive", "uniform"}));
}

core::GridKind grid_kind_for(const GridChoice& choice) {
  return choice.given.value_or(core::GridKind::kAdaptive);
}

std::vector<GridLevel> grid_levels(const core::Grid& grid) {
  std::vector<GridLevel> levels(grid.depth() + 1);
  auto count_leaf = [&](GridLevel& l, std::uint32_t leaf) {
    const std::uint32_t n = grid.cell_start[leaf + 1] - grid.cell_start[leaf];
    ++l.leaf_cells;
    l.empty_cells += n == 0;
    l.references += n;
  };
  if (grid.sub_grids.empty()) {  // uniform, or adaptive with nothing refined: the top grid alone
    levels[0].grids = 1;
    levels[0].cells = grid.info.cell_count();
    for (std::uint32_t c = 0; c < grid.leaf_cells(); ++c) count_leaf(levels[0], c);
    return levels;
  }
  for (const core::SubGrid& s : grid.sub_grids) {
    GridLevel& l = levels[s.level];
    ++l.grids;
    l.cells += s.info.cell_count();
    for (std::uint32_t c = 0; c < s.info.cell_count(); ++c)
      if (!(grid.cell_entries[s.first_entry + c] & core::kSubGridEntry)) count_leaf(l, s.first_entry + c);
    if (s.large_list) count_leaf(l, s.first_entry + s.info.cell_count());
  }
  return levels;
}

std::uint32_t top_large_primitives(const core::Grid& grid) {
  const std::uint32_t leaf = core::SubGridTables{grid.sub_grids, grid.cell_entries}.top_large_leaf();
  return leaf == core::kNoLeaf ? 0 : grid.cell_start[leaf + 1] - grid.cell_start[leaf];
}

nlohmann::json grid_json(const core::Grid& grid) {
  nlohmann::json levels = nlohmann::json::array();
  for (const GridLevel& l : grid_levels(grid))
    levels.push_back({{"grids", l.grids},
                      {"cells", l.cells},
                      {"leaf_cells", l.leaf_cells},
                      {"empty_leaf_cells", l.empty_cells},
                      {"references", l.references}});
  return {{"kind", core::grid_kind_name(grid.kind())},
          {"resolution", {grid.info.res[0], grid.info.res[1], grid.info.res[2]}},
          {"large_primitives", top_large_primitives(grid)},
          {"cells", grid.info.cell_count()},
          {"leaf_cells", grid.leaf_cells()},
          {"sub_grids", grid.sub_grid_count()},
          {"depth", grid.depth()},
          {"levels", levels},
          {"references", grid.references()},
          {"empty_cells", grid.empty_cells()},
          {"bytes", grid.bytes()}};
}

std::string grid_summary(const core::Grid& grid) {
  const auto& r = grid.info.res;
  if (grid.kind() == core::GridKind::kUniform)
    return fmt::format("uniform {}x{}x{}, {} references", r[0], r[1], r[2], grid.references());
  const std::uint32_t large = top_large_primitives(grid);
  return fmt::format("adaptive {}x{}x{} top grid{}, {} sub-grids (depth {}), {} leaf cells, {} references", r[0], r[1],
                     r[2], large ? fmt::format(" beside {} large primitive{}", large, large == 1 ? "" : "s") : "",
                     grid.sub_grid_count(), grid.depth(), grid.leaf_cells(), grid.references());
}

void add_pack_cells_option(CLI::App& cmd, std::uint32_t& pack_min) {
  cmd.add_option_function<std::string>(
         "--pack-cells",
         [&pack_min](const std::string& v) { pack_min = v == "off" ? 0 : std::uint32_t(std::stoul(v)); },
         fmt::format("Grid tracing: cells listing at least N primitives, all triangles (or, outside svm, all "
                     "spheres), keep them in SIMD blocks of {} and are tested a block at a time (same hits); off = "
                     "every cell walks its primitive list, as the paper's tracer [default: {} in sequential and "
                     "shared modes, bench and validate; off in svm, which then pages the triangle blocks (pages of "
                     "512 B or more); replicated and dataflow: off only]",
                     raynode::core::kBlockLanes, raynode::core::kDefaultPackMin))
      ->check(CLI::IsMember({"off"}) | CLI::Range(1, 1 << 20));
}

CLI::Validator finite_range(double lo, double hi) {
  std::string bounds;  // " in [0, 1]", " >= 0", ""
  if (std::isfinite(lo) && std::isfinite(hi)) bounds = fmt::format(" in [{:g}, {:g}]", lo, hi);
  else if (std::isfinite(lo)) bounds = fmt::format(" >= {:g}", lo);
  else if (std::isfinite(hi)) bounds = fmt::format(" <= {:g}", hi);
  const std::string what = "a finite number" + bounds;
  return CLI::Validator(
      [lo, hi, what](std::string& text) -> std::string {
        double v = 0;
        if (!parse_double(text, v)) return fmt::format("must be {}, got '{}'", what, text);
        if (!std::isfinite(v) || v < lo || v > hi) return fmt::format("must be {}, got '{}'", what, text);
        return {};
      },
      bounds.empty() ? "FLOAT (finite)" : "FLOAT" + bounds);
}

CLI::Validator finite_positive() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        double v = 0;
        if (!parse_double(text, v) || !std::isfinite(v) || !(v > 0))
          return fmt::format("must be a finite number > 0, got '{}'", text);
        return {};
      },
      "FLOAT > 0");
}

namespace {

/// "svm", "replicated or svm", "replicated, svm or dataflow".
std::string or_list(const std::vector<std::string>& items) {
  std::string s;
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (i > 0) s += i + 1 == items.size() ? " or " : ", ";
    s += items[i];
  }
  return s;
}

/// "--mode svm", or "--modes dataflow,replicated" for several.
std::string given_modes(const std::vector<std::string>& modes) {
  std::string s = modes.size() == 1 ? "--mode " : "--modes ";
  for (std::size_t i = 0; i < modes.size(); ++i) s += (i ? "," : "") + modes[i];
  return s;
}

/// An option only some modes read, and what they read it for.
struct ModeOptionRule {
  const char* option;
  std::vector<std::string> modes;
  const char* what;
};

const std::vector<ModeOptionRule>& mode_option_rules() {
  static const std::vector<std::string> kNodeModes{"replicated", "svm", "dataflow"};
  static const std::vector<std::string> kControl{"replicated", "svm"};
  static const std::vector<std::string> kSvm{"svm"};
  static const std::vector<std::string> kDataflow{"dataflow"};
  static const std::vector<ModeOptionRule> rules{
      {"--machine", kNodeModes, "the emulated machine's description"},
      {"--node-memory", kNodeModes, "the emulated machine's memories"},
      {"--network", kNodeModes, "the emulated machine's network"},
      {"--network-scale", kNodeModes, "the emulated machine's network"},
      {"--contention", kNodeModes, "the emulated machine's network"},
      {"--calibrate", kNodeModes, "the emulated machine's virtual time"},
      {"--topology", kNodeModes, "the emulated machine's network"},
      {"--schedule-window", kNodeModes, "the emulated machine's scheduler"},
      {"--mail-wakeups", kNodeModes, "the emulated machine's scheduler"},
      {"--clock", kNodeModes, "the emulated machine's virtual time"},
      {"--corun-slowdown", kNodeModes, "the emulated machine's virtual time"},
      {"--stall-timeout", kNodeModes, "a run on the emulated machine"},
      {"--transport", kNodeModes, "where the machine's participants run"},
      {"--work-item", kControl, "static submaps and work requests"},
      {"--work-requests", kControl, "static submaps and work requests"},
      {"--work-grants", kControl, "static submaps and work requests"},
      {"--submaps", kControl, "static submaps and work requests"},
      {"--page-size", kSvm, "the shared virtual memory's pages"},
      {"--cache", kSvm, "the shared virtual memory's page cache"},
      {"--directory-order", kSvm, "the shared virtual memory's cell directory"},
      {"--primitive-order", kSvm, "the shared virtual memory's primitive records"},
      {"--page-fetch", kSvm, "the shared virtual memory's page faults"},
      {"--partition", kDataflow, "its regions"},
      {"--queue-capacity", kDataflow, "its ray queues"},
      {"--send-queue", kDataflow, "its ray queues"},
  };
  return rules;
}

}  // namespace

void check_mode_options(const CLI::App& cmd, const std::vector<std::string>& modes) {
  auto given = [&](const char* name) {
    const CLI::Option* opt = cmd.get_option_no_throw(name);
    return opt != nullptr && opt->count() > 0;
  };
  // An option's value as parsed, or its default (capture_default_str) when not given.
  auto value = [&](const char* name, const char* absent) {
    const CLI::Option* opt = cmd.get_option_no_throw(name);
    return opt != nullptr ? opt->as<std::string>() : std::string(absent);
  };
  auto read_by_any = [&](const std::vector<std::string>& readers) {
    return std::any_of(modes.begin(), modes.end(), [&](const std::string& m) {
      return std::find(readers.begin(), readers.end(), m) != readers.end();
    });
  };
  for (const ModeOptionRule& r : mode_option_rules()) {
    if (!given(r.option) || read_by_any(r.modes)) continue;
    throw UsageError(fmt::format("{} is for --mode {} ({}), not {}; leave {} out", r.option, or_list(r.modes), r.what,
                                 given_modes(modes), r.option));
  }
  if (given("--network-scale")) {
    const std::string network = value("--network", "none");
    if (network != "ipsc2")
      throw UsageError(fmt::format("--network-scale is for --network ipsc2 (this machine's seconds per ray), not "
                                   "--network {}; leave --network-scale out",
                                   network));
  }
  // --subsample: dataflow's load estimate, or the one that cuts balanced submaps.
  if (given("--subsample") && !read_by_any({"dataflow"})) {
    const bool control = read_by_any({"replicated", "svm"});
    if (!control || value("--submaps", "square") != "balanced")
      throw UsageError(fmt::format("--subsample is for --mode dataflow, or --mode replicated or svm with --submaps "
                                   "balanced (the host's load estimate), not {}{}; leave --subsample out",
                                   given_modes(modes), control ? " with --submaps square" : ""));
  }
}

}  // namespace raynode::apps
