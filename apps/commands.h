// raynode CLI: each subcommand registers itself on the CLI11 app. Only apps/
// catches exceptions and turns them into messages and exit codes:
//   0 success; 1 unreadable/malformed scene or failed check (e.g. validate
//   mismatches); 2 bad command line or bad value.
#pragma once

#include <CLI/CLI.hpp>
#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/cost_model.h"
#include "core/grid.h"
#include "core/scene_source.h"

namespace raynode::apps {

/// A usage error detected after parsing (a value CLI11 cannot check); exit 2.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The user interrupted a child process (Ctrl-C while a plot script ran);
/// main() prints what() and exits with status 130, as the shell does for
/// SIGINT. What was finished before is kept.
class Interrupted : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Adds the SCENE positional, --tessellate, --scale, --translate and --floor to a subcommand.
void add_scene_options(CLI::App& cmd, core::SceneSource& source);

/// Adds --floor K (core::SceneSource::floor, K in [1, 1e6]: a stadium floor
/// K times the scene's width, core::add_stadium_floor); `floor` must outlive
/// the parse.
void add_floor_option(CLI::App& cmd, double& floor);

/// Adds --eye X,Y,Z, --at X,Y,Z, --up X,Y,Z and --fov DEG to a subcommand:
/// parts of the view that replace the scene's (core::ViewOverride; scene
/// file coordinates, before --scale and --translate). Each number must be
/// finite and --fov in (0, 180) (CLI errors, exit 2); the view they give is
/// checked by core::load_scene (std::invalid_argument, exit 2). `view` must
/// outlive the parse.
void add_camera_options(CLI::App& cmd, core::ViewOverride& view);

/// Adds --skip-empty on|off (core::GridParams::skip_empty) to a subcommand;
/// `skip_empty` must outlive the parse.
void add_skip_empty_option(CLI::App& cmd, bool& skip_empty);

/// A scene source for the commands that trace rays (render, validate, bench
/// accel, bench nodes, bench quality, bench cost-model, sweep): `spec` with
/// --tessellate R, moved so that its eye lies at the origin
/// (core::eye_at_origin), where the tracer's arithmetic is finest; scene
/// info and scene write keep its coordinates.
inline core::SceneSource tracing_source(std::string spec = {}, int tessellate = 0) {
  core::SceneSource s(std::move(spec), tessellate);
  s.eye_origin = true;
  return s;
}

/// Adds --grid-density LAMBDA (cells per primitive, in [0.01, 1000]) to a
/// subcommand; `density` must outlive the parse. See set_grid_density.
void add_grid_density_option(CLI::App& cmd, float& density);
/// Applies --grid-density to a grid build: the uniform grid's cells per
/// primitive, and the adaptive grid's at every level (its top grid's
/// lambda_top and each sub-grid's lambda; core/grid.h), so that the option
/// changes the grid of every scene, not only of those with sub-grids.
void set_grid_density(core::GridParams& params, float density);

/// --grid as given on the command line (unset: the command's default).
struct GridChoice {
  std::optional<core::GridKind> given;  ///< the value of --grid, if given
};
/// Adds --grid adaptive|uniform (core::GridKind) to a subcommand; `choice`
/// must outlive the parse.
void add_grid_option(CLI::App& cmd, GridChoice& choice);
/// The grid kind --grid gave, else adaptive (every mode reads both: svm
/// pages either, dataflow builds each region's local grid of this kind).
core::GridKind grid_kind_for(const GridChoice& choice);

/// The grid's description for JSON outputs (stats, scene info, bench):
/// kind, top resolution, large primitives beside the top grid, cells, leaf
/// cells, sub-grids, depth, references, empty leaf cells, bytes.
nlohmann::json grid_json(const core::Grid& grid);
/// One level of a grid's hierarchy (0: the top grid; a uniform grid has
/// only that): its grids, their cells, the cells that are leaves (hold no
/// sub-grid), the empty ones among them and the primitive ids the leaves list.
struct GridLevel {
  std::uint64_t grids = 0, cells = 0, leaf_cells = 0, empty_cells = 0, references = 0;
};
/// Per level, as GridLevel (size: depth() + 1).
std::vector<GridLevel> grid_levels(const core::Grid& grid);
/// The scene's large primitives listed beside an adaptive grid's top grid
/// (core/grid.h; 0 for a uniform grid or when there are none).
std::uint32_t top_large_primitives(const core::Grid& grid);
/// One line: "adaptive 24x24x24 top grid, 1234 sub-grids (depth 2), 98765
/// leaf cells, 123456 references" (with " beside 2 large primitives" after
/// "top grid" when there are some) or "uniform 64x64x64, 123456 references".
std::string grid_summary(const core::Grid& grid);

/// Adds --json [FILE] to a subcommand, the one convention of every command
/// that writes JSON: `--json` alone (or `--json -`) writes to stdout,
/// `--json FILE` (or `--json=FILE`) to FILE, through OutputFiles (checked
/// before any work, replaced whole at the end). After the parse `path` is
/// "" when --json was not given, else "-" or the file. A FILE with a scene
/// file's extension (.nff, .gz, a mesh's) is refused (exit 2): it is a
/// scene that --json took for its file. `path` must outlive the parse.
CLI::Option* add_json_option(CLI::App& cmd, std::string& path, const std::string& what);

/// Adds --pack-cells N|off (core/cell_blocks.h: cells listing at least N
/// triangles are tested in SIMD blocks; 0 = off) to a subcommand;
/// `pack_min` must outlive the parse.
void add_pack_cells_option(CLI::App& cmd, std::uint32_t& pack_min);

/// A CLI11 check for a floating-point option: a finite number in [lo, hi]
/// (either bound may be +-infinity, meaning none). NaN and infinities are
/// refused, "must be a finite number in [0, 1], got 'nan'": CLI::Range
/// lets NaN through, as every compare with it is false, and prints an open
/// bound as 1.797...e308 written out in full.
CLI::Validator finite_range(double lo, double hi);
/// finite_range's open bound.
inline constexpr double kNoBound = std::numeric_limits<double>::infinity();
/// finite_range for a number > 0 ("must be a finite number > 0").
CLI::Validator finite_positive();

/// Refuses options given on `cmd`'s command line that none of `modes`
/// ("sequential", "shared", "replicated", "svm", "dataflow") reads, so that
/// no option is silently ignored: a node option (--node-memory, --clock,
/// --stall-timeout, ...) outside the node modes, the static submaps' and work
/// requests' options outside replicated and svm, --page-size, --cache and
/// --directory-order and --primitive-order outside svm, --partition, --queue-capacity and --send-queue outside
/// dataflow, --subsample where neither dataflow nor --submaps balanced
/// reads it, --network-scale without --network ipsc2 (--submaps and
/// --network are read from `cmd`: their values, or their defaults when not
/// given). Options `cmd` does not have, or that were not given, pass.
/// Throws UsageError naming the option, the modes that read it and the
/// mode(s) given (exit 2).
void check_mode_options(const CLI::App& cmd, const std::vector<std::string>& modes);

void register_scene_commands(CLI::App& app);
void register_validate_command(CLI::App& app);
void register_bench_command(CLI::App& app);
/// bench mailbox, bench nodes (after register_bench_command).
void register_bench_nodes_commands(CLI::App& app);
void register_render_command(CLI::App& app);
/// sweep nodes|cache|page-size (apps/cmd_sweep.cpp).
void register_sweep_commands(CLI::App& app);
/// bench mpi (after register_bench_command; apps/cmd_bench_mpi.cpp).
void register_bench_mpi_command(CLI::App& app);
/// bench quality (after register_bench_command; apps/cmd_bench_quality.cpp).
void register_bench_quality_command(CLI::App& app);
/// bench cost-model (after register_bench_command; apps/cmd_bench_cost_model.cpp).
void register_bench_cost_model_command(CLI::App& app);
/// The model clock's unit costs fitted on this host as `raynode bench
/// cost-model` fits them with its defaults (its six scenes, 128x128, 3
/// passes a tile, the pager's costs too), quietly: about two seconds.
core::CostModel fit_cost_model_on_host();

}  // namespace raynode::apps
