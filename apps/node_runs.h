// One render on the emulated machine as the experiment commands measure it:
// `raynode render` (node modes), `raynode bench nodes` and `raynode sweep
// nodes|cache|page-size` share the options (NodeRunOptions,
// add_node_run_options), their parsing into a
// NodeRunSpec, and run_node_mode, which renders one frame in replicated, svm
// or dataflow mode and keeps the figures a table row needs (NodeRun).
//
// Data flow: command line -> NodeRunOptions -> make_node_run_spec (parses
// sizes, calibrates the network once per series so that every run, T_1
// included, has the same cost model) -> run_best(db, grid, spec, nodes,
// repeat) -> NodeRun -> table / CSV row. Speedup and efficiency follow the
// paper: speedup = T_1 / T_p with T_1 the same mode's one-node run,
// efficiency = speedup / p (nodes/machine.h).
//
// A run that cannot start because the database (or a requested cache) does
// not fit a node's --node-memory is not an error here: run_node_mode reports
// it as NodeRun::fits = false with the mode's message naming the sizes, so a
// sweep can mark the point skipped and go on.
#pragma once

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <span>
#include <vector>

#include "apps/commands.h"
#include "apps/machine_file.h"
#include "core/database.h"
#include "core/grid.h"
#include "core/render.h"
#include "dataflow/dataflow.h"
#include "modes/modes.h"
#include "nodes/machine.h"
#include "control/submap_plan.h"
#include "nodes/network.h"
#include "svm/paged_database.h"

namespace raynode::apps {

/// Help text of --mail-wakeups (render and the node benchmarks).
inline constexpr const char* kMailWakeupsHelp =
    "Node modes: how a node thread that holds no run permit is woken for its mail: scheduled (by the "
    "virtual-time scheduler when a core is free, serving all its mail at once), immediate (by each "
    "message) or auto (scheduled for dataflow, immediate for replicated and svm, whose nodes block for "
    "each reply). Same virtual times and images; only the wall time differs";

/// Help text of --directory-order (render and the node benchmarks).
inline constexpr const char* kDirectoryOrderHelp =
    "svm: order of the paged cell directory: linear (cell order, the paper's), bricked (a page per brick of "
    "cells, so a ray meets a new directory page every few cells on any axis: about half the directory "
    "pages a node fetches) or auto (bricked on more than one node; on one node every page is home and the "
    "linear walk is cheaper). Same images";

/// Help text of --primitive-order (render and the node benchmarks).
inline constexpr const char* kPrimitiveOrderHelp =
    "svm: order of the paged primitive records: file (the database's, the paper's), cell (as the cells, "
    "walked in the directory's order, first list them, so that a cell's primitives share pages) or auto "
    "(with the adaptive grid, the one whose cell lists name fewer pages, cells weighted by their "
    "surface; file with --grid uniform). Same images";

/// The machine and mode options as typed on the command line (strings where
/// the text is parsed later, so errors can name the option).
struct NodeRunOptions {
  int width = 256, height = 256;        ///< pixels
  std::string machine;                  ///< --machine NAME|FILE ("": none); sets the defaults below
  std::optional<NetworkFigures> network_figures;  ///< --machine FILE's network figures (network "custom")
  std::string node_memory = "4MiB";     ///< per node (the iPSC/2's 4 MiB)
  std::string network = "ipsc2";        ///< none, ipsc2, cluster
  std::string contention = "auto";      ///< link contention: auto (the network's), on, off
  double network_scale = 0;             ///< ipsc2: this machine's seconds per ray; 0 = calibrate once
  std::string topology = "hypercube";   ///< hypercube, ring, torus
  std::string work_item = "3x3";        ///< replicated, svm: pixels per work item
  double schedule_window_us = 200;      ///< virtual-time scheduling window, microseconds
  std::string mail_wakeups = "auto";   ///< --mail-wakeups: auto, scheduled or immediate
  std::string clock = "cpu";            ///< cpu or model (nodes::ComputeClock)
  double corun_slowdown = 1;            ///< model clock, > 1 node: factor on a node's work (nodes::MachineParams)
  std::optional<core::CostModel> cost_model;  ///< a machine description's unit costs; else the built-in model
  std::string shadow_rays = "facing";   ///< facing or all (core::ShadowRays)
  std::string calibrate = "auto";       ///< model clock: auto, on or off (calibrate_model_clock)
  std::string work_requests = "ring";   ///< ring, last-grantor or off (nodes::WorkRequestRoute)
  /// auto, item, nearest or half (nodes::WorkGrant): auto is item in the
  /// emulator (the paper's) and half on MPI ranks (nodes::resolved_work_grant).
  std::string work_grants = "auto";
  std::string submaps = "square";       ///< square or balanced (control::SubmapRule)
  double stall_timeout_s = 60;          ///< wall seconds without a message before a run stops; 0 = never
  double timeout_s = 0;                 ///< per run, wall seconds; 0 = none
  int repeat = 1;                       ///< runs per point; the lowest T_p is kept
  bool skip_empty = true;               ///< grid: empty-space jumps (core::GridParams::skip_empty)
  GridChoice grid;                      ///< --grid (uniform when a mode is svm)
  // svm
  std::uint32_t page_size = 1024;       ///< bytes
  std::string directory_order = "auto"; ///< auto, linear or bricked (svm::parse_directory_order)
  std::string primitive_order = "auto"; ///< auto, file or cell (svm::parse_primitive_order)
  std::string cache;                    ///< "" = all free memory, "N" pages or "P%" of the database
  // dataflow
  int subsample = 8;                    ///< load estimate (and --submaps balanced's): one pixel per NxN block
  std::string partition = "balanced";   ///< balanced or equal
  std::uint32_t queue_capacity = 0;     ///< node mailbox slots; 0 = the mode's default
  std::uint32_t send_queue = 0;         ///< sending queue slots; 0 = the node memory left (the paper's rule)
};

/// Adds --shadow-rays (facing or all) to `c`, bound to `word`: render and
/// the node commands take it alike.
inline CLI::Option* add_shadow_rays_option(CLI::App& c, std::string& word) {
  return c
      .add_option("--shadow-rays", word,
                  "Lights a hit casts shadow rays to: facing (those the surface faces; a light behind adds "
                  "nothing) or all (every light, as the paper's tracer counted its rays: the same image, more "
                  "rays)")
      ->check(CLI::IsMember({"facing", "all"}))
      ->capture_default_str();
}

/// --shadow-rays' word (checked by the CLI): kAll for "all", else kFacing.
inline core::ShadowRays shadow_rays_from_name(const std::string& word) {
  return word == "all" ? core::ShadowRays::kAll : core::ShadowRays::kFacing;
}

/// Which options add_node_run_options adds besides the machine's.
struct NodeRunOptionSet {
  bool experiment = true;  ///< --width, --height, --grid, --skip-empty, --timeout (per run), --repeat
  bool page_size = true;   ///< --page-size, --directory-order, --primitive-order (svm)
  bool cache = false;      ///< --cache N|P% (svm)
  bool dataflow = true;    ///< --partition, --queue-capacity, --send-queue
};

/// The one declaration of the emulated machine's and the node modes'
/// options, for every command that runs them (render, bench nodes, sweep):
/// --machine (apps/machine_file.h; first, so that the others override it),
/// --node-memory, --network, --network-scale, --topology, --work-item,
/// --work-requests, --work-grants, --submaps, --subsample,
/// --schedule-window, --mail-wakeups, --clock, --stall-timeout and, per
/// `set`, the experiment's, svm's and dataflow's. Defaults are `o`'s
/// current values (the paper's machine: 4 MiB nodes, the iPSC/2 network,
/// a hypercube), shown in --help. `o` must outlive `cmd`.
void add_node_run_options(CLI::App& cmd, NodeRunOptions& o, NodeRunOptionSet set = {});

/// --cache: "N" pages into `pages`, or "P%" of the database's pages into
/// `fraction` (0..1]; "" changes nothing. Throws UsageError.
void parse_cache(const std::string& text, std::uint32_t& pages, double& fraction);

/// Everything a run needs besides the node count, parsed and checked: the
/// node modes' parameters (modes/modes.h), the render's, and the repeats.
struct NodeRunSpec : modes::NodeModeParams {
  core::RenderParams render;          ///< width, height (the rest: defaults)
  int repeat = 1;
};

/// Parses `o` into a spec: byte sizes, topology, work item, clock, and the
/// network model, calibrated here once (ipsc2 scales to this machine's
/// seconds per ray: measured CPU time, or the cost model's under --clock
/// model). Throws UsageError naming the option on a bad value.
NodeRunSpec make_node_run_spec(const NodeRunOptions& o);

/// Pixels on a side of the model clock's calibration sample, and the
/// rounds of it (each times the scene, then teapot:8; the median round's
/// ratio counts).
inline constexpr int kCalibrationSample = 128;
inline constexpr int kCalibrationRounds = 7;

/// The model clock held against this machine on one scene: a sample of it
/// (the sequential tracer at kCalibrationSample pixels square, its thread
/// CPU time) against the cost model's seconds for the same operation
/// counts, relative to the same measure on teapot:8, the scene the
/// network's scale is taken on, timed right after it. The ratio is the
/// median of kCalibrationRounds such pairs, so that a burst of the host's
/// load during a few samples, or a drift of its speed, does not move it. A
/// host faster or slower than the model's as a whole therefore does not
/// count as an error; a scene whose operations cost this host more or less
/// than the model says, relative to Teapot, does. A scene whose sample
/// does exactly the reference's operations (teapot:8 itself) has ratio 1
/// by definition and is not timed against it.
struct ModelCalibration {
  bool measured = false;            ///< a sample was timed (model clock, --calibrate not off)
  double cpu_s = 0, model_s = 0;    ///< the scene's sample: CPU seconds (the median round's) and modelled seconds
  double reference_cpu_s = 0, reference_model_s = 0;  ///< teapot:8's, of the same round
  double ratio = 1;                 ///< (cpu_s / model_s) / (reference_cpu_s / reference_model_s)
  bool same_work = false;           ///< the sample's counts are the reference's: ratio 1, not timed
  bool applied = false;             ///< the unit costs were scaled by `ratio` for this command's runs
  /// {"sample", "cpu_s", "model_s", "reference", "error" (ratio - 1), "applied", "same_work", "threshold"}; null if not measured.
  nlohmann::json to_json() const;
  /// The line commands print: "model clock: +40% against Teapot on this host, unit costs scaled by it (--calibrate)".
  std::string summary() const;
};
/// |ratio - 1| above which --calibrate auto scales the model.
inline constexpr double kCalibrateAbove = 0.15;

/// Under the model clock (machine.clock), measures machine.cost_model on
/// `db` (ModelCalibration; spp, depth and weight cut-off from `render`) and,
/// as `policy` says ("auto": when off by more than kCalibrateAbove; "on":
/// always; "off": never, and nothing is measured), scales every unit cost
/// of machine.cost_model by the ratio. The network model (made before,
/// from the unscaled model) keeps its scale. Call once per scene, before
/// all the runs compared. Costs 2 x (kCalibrationRounds + 1) 128x128 sequential renders
/// (2 when the scene does the reference's work).
ModelCalibration calibrate_model_clock(nodes::MachineParams& machine, const core::RenderParams& render,
                                       const core::Database& db, const core::Grid& grid, const std::string& policy);

/// "3x3" -> {3, 3}; throws UsageError.
std::pair<int, int> parse_work_item(const std::string& text);

/// What one node-mode render measured. Mode counters are std::nullopt where
/// the mode has none (e.g. grants in dataflow, miss ratio outside svm).
struct NodeRun {
  bool fits = true;            ///< false: the run did not start, see `skipped`
  std::string skipped;         ///< why it did not fit (the mode's message naming the sizes)
  std::size_t node_memory = 0; ///< bytes per node it ran with
  double wall_s = 0;           ///< real seconds of the render call
  double parallel_time_s = 0;  ///< T_p, virtual seconds
  double work_s = 0;           ///< busy virtual seconds summed over the nodes
  std::uint64_t rays = 0;      ///< rays traced, all kinds
  std::uint64_t mail_checks = 0;  ///< the nodes' looks for mail, summed (nodes::NodeCounters::mail_checks)
  std::optional<std::uint64_t> grants;  ///< replicated, svm: work items granted
  /// replicated, svm with --submaps balanced: the host's load estimate,
  /// traced before the run and outside virtual time, in the run's clock's
  /// seconds (its modelled seconds under the model clock, its host wall
  /// seconds under the CPU clock; 0 at one node, which traces none).
  std::optional<double> estimate_s;
  // svm
  std::optional<double> miss_ratio;        ///< page faults per object access
  std::optional<double> cache_miss_ratio;  ///< page faults per non-home page lookup (once per pixel), from the cache's filling (0 if it never fills)
  std::optional<double> pages_per_pixel;   ///< distinct pages per pixel (the paper's Table 2)
  std::optional<std::uint64_t> accesses;             ///< object accesses through the page tables
  std::optional<std::uint64_t> cache_page_accesses;  ///< of them, to cached (non-home) pages
  std::optional<double> communication_rate_bytes_per_s;  ///< page bytes received by all nodes / T_p
  std::optional<std::uint64_t> page_requests;
  std::optional<std::uint64_t> evictions;
  std::optional<std::uint32_t> cache_pages;  ///< cache frames of node 0
  std::optional<std::uint32_t> pages_total;  ///< pages of the shared virtual memory
  std::optional<std::uint64_t> database_bytes;  ///< shared virtual memory bytes (svm)
  // dataflow
  std::optional<std::uint64_t> ray_messages;  ///< between nodes plus spills
  std::optional<double> spill_fraction;       ///< rays spilled to the host / ray messages
  std::optional<double> average_load;         ///< mean over nodes of busy / T_p
};

/// Renders one frame of `db` in `mode` ("replicated", "svm", "dataflow") on
/// `nodes` nodes as `spec` says (`node_memory`, when non-zero, replaces the
/// spec's). Returns fits = false when the mode refuses to start because
/// something does not fit a node, or a node runs out of memory; throws
/// UsageError for bad parameters, nodes::NodeError for other failures.
NodeRun run_node_mode(const core::Database& db, const core::Grid& grid, const std::string& mode,
                      const NodeRunSpec& spec, std::uint32_t nodes, std::size_t node_memory = 0);

/// run_node_mode `spec.repeat` times; the run with the lowest T_p (or the
/// first that did not fit).
NodeRun run_best(const core::Database& db, const core::Grid& grid, const std::string& mode, const NodeRunSpec& spec,
                 std::uint32_t nodes, std::size_t node_memory = 0);

/// Node memory for a one-node run (T_1) of a database that does not fit
/// --node-memory: the arena is only a budget, so this is accounting, not
/// memory taken. At most the host's physical memory (t1_fallback_memory),
/// as the machine allows no more (nodes::check_nodes_fit_host).
inline constexpr std::size_t kT1FallbackMemory = std::size_t(64) << 30;
/// kT1FallbackMemory, or the host's physical memory when that is less. Bytes.
inline std::size_t t1_fallback_memory() {
  const std::size_t host = nodes::host_physical_memory();
  return host > 0 && host < kT1FallbackMemory ? host : kT1FallbackMemory;
}

/// The median of `values` (the mean of the middle two for an even count);
/// NaN for none. Takes a copy: the caller's order stays.
inline double median(std::vector<double> values) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  const std::size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + std::ptrdiff_t(mid), values.end());
  if (values.size() % 2 == 1) return values[mid];
  const double upper = values[mid];
  return (*std::max_element(values.begin(), values.begin() + std::ptrdiff_t(mid)) + upper) / 2;
}

/// Efficiency with a serial step before the run charged:
/// T_1 / (n x (T_p + serial_s)), the paper's efficiency when serial_s is 0;
/// 0 without T_1 or T_p (t1 <= 0 or tp + serial_s <= 0). Seconds on one clock.
inline double charged_efficiency(double t1, double tp, int n, double serial_s) {
  const double t = tp + serial_s;
  return t1 > 0 && t > 0 && n > 0 ? t1 / (double(n) * t) : 0.0;
}

/// "1.5 s", "2 min 10 s", "1 h 02 min" for progress lines.
std::string format_duration(double seconds);
/// "3:12:02" (hours:minutes:seconds, rounded to the second), as the
/// paper's Table 3 writes times; "?" for a negative or non-finite value.
std::string hours_minutes_seconds(double seconds);

/// Seconds since `t0` on the steady clock.
double seconds_since(std::chrono::steady_clock::time_point t0);

/// Wall seconds per round trip of a `bytes`-byte kTest message between
/// nodes 0 and 1 of a machine built from `p` (2 or more nodes; the payload
/// limit is raised to `bytes` if need be; other nodes idle), over `trips`
/// trips: send, the other's receive and reply, the receive. Measured on
/// node 0, so valid in the process that runs it (`bench mailbox`; under a
/// transport, `bench mpi` on rank 0).
double node_round_trip_s(nodes::MachineParams p, std::size_t bytes, std::uint64_t trips);

}  // namespace raynode::apps
