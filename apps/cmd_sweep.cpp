// `raynode sweep nodes|cache|page-size SCENE`: the paper's experiments as
// commands. Each renders SCENE on the emulated machine for a
// series of points, writes PREFIX.csv and plots it to PREFIX.png (through
// the embedded PREFIX.plot.py, apps/sweep_plots.h), shows one progress line
// per run on stderr and a table on stdout.
//
//  * sweep nodes: speedup and efficiency against the node count, one curve
//    per mode (replicated, svm, dataflow): the paper's Figures 5 and 7.
//    T_1 = each mode's own one-node run.
//  * sweep cache: svm at a fixed node count with the page cache limited to
//    a share of the database: efficiency, miss ratio, communication rate
//    against cache size (Figures 8, 9, 10). T_1 = the one-node svm run (all
//    pages home).
//  * sweep page-size: svm at a fixed node count for several page sizes
//    (the paper fixed 1 KiB). T_1 = the one-node run at each page size.
//
// A point that does not fit a node's memory (a mode's error naming the
// sizes) becomes a "skipped" row with the reason, and the sweep goes on;
// only a sweep where nothing fits stops with that reason (exit 2). A
// one-node run (T_1) whose database does not fit --node-memory runs with the
// budget raised (kT1FallbackMemory: accounting only), and says so: the
// paper likewise had to estimate one-node times it could not measure.
#include <fmt/core.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "apps/commands.h"
#include "apps/node_runs.h"
#include "apps/output_files.h"
#include "apps/plot.h"
#include "apps/sweep_plots.h"
#include "apps/sweep_points.h"
#include "core/database.h"
#include "core/grid.h"
#include "core/scene_source.h"
#include "nodes/arena.h"

namespace raynode::apps {

namespace {

// --- Tables: CSV and the stdout summary -------------------------------------

/// Rows of string cells under named columns; cells left unset stay empty
/// (a counter the mode does not have).
class Table {
 public:
  explicit Table(std::vector<std::string> columns) : columns_(std::move(columns)) {
    for (std::size_t i = 0; i < columns_.size(); ++i) index_[columns_[i]] = i;
  }
  std::size_t add_row() {
    rows_.emplace_back(columns_.size());
    return rows_.size() - 1;
  }
  bool has(const std::string& column) const { return index_.count(column) != 0; }
  /// Sets a cell; a column this table lacks is ignored (the fillers are
  /// shared by sweeps with different columns).
  void set(std::size_t row, const std::string& column, std::string value) {
    const auto it = index_.find(column);
    if (it != index_.end()) rows_[row][it->second] = std::move(value);
  }
  const std::string& get(std::size_t row, const std::string& column) const {
    static const std::string empty;
    const auto it = index_.find(column);
    return it == index_.end() ? empty : rows_[row][it->second];
  }
  std::size_t size() const { return rows_.size(); }

  /// The table as CSV (RFC 4180: cells with a comma, quote or newline are
  /// quoted).
  std::string csv_text() const {
    std::string out;
    auto line = [&out](const std::vector<std::string>& cells) {
      for (std::size_t i = 0; i < cells.size(); ++i) {
        if (i) out += ',';
        const std::string& c = cells[i];
        if (c.find_first_of(",\"\n\r") == std::string::npos) {
          out += c;
          continue;
        }
        out += '"';
        for (char ch : c) out += ch == '"' ? std::string("\"\"") : std::string(1, ch);
        out += '"';
      }
      out += '\n';
    };
    line(columns_);
    for (const auto& r : rows_) line(r);
    return out;
  }

  /// `columns` as a right-aligned text table ("-" for an empty cell);
  /// `labels` are the headers (same length).
  void print(const std::vector<std::string>& columns, const std::vector<std::string>& labels) const {
    std::vector<std::size_t> width(columns.size());
    for (std::size_t c = 0; c < columns.size(); ++c) {
      width[c] = labels[c].size();
      for (std::size_t r = 0; r < rows_.size(); ++r) width[c] = std::max(width[c], cell(r, columns[c]).size());
    }
    std::string out;
    for (std::size_t c = 0; c < columns.size(); ++c) out += fmt::format("{}{:>{}}", c ? " " : "", labels[c], width[c]);
    fmt::print("{}\n", out);
    for (std::size_t r = 0; r < rows_.size(); ++r) {
      out.clear();
      for (std::size_t c = 0; c < columns.size(); ++c)
        out += fmt::format("{}{:>{}}", c ? " " : "", cell(r, columns[c]), width[c]);
      fmt::print("{}\n", out);
    }
  }

 private:
  /// For the screen: "-" for empty, 4 significant digits for a fraction.
  std::string cell(std::size_t r, const std::string& column) const {
    const std::string& v = get(r, column);
    if (v.empty()) return "-";
    if (v.find_first_of(".e") == std::string::npos) return v;
    char* end = nullptr;
    const double d = std::strtod(v.c_str(), &end);
    return *end == '\0' ? fmt::format("{:.4g}", d) : v;
  }
  std::vector<std::string> columns_;
  std::map<std::string, std::size_t> index_;
  std::vector<std::vector<std::string>> rows_;
};

std::string num(double v) { return fmt::format("{:.6g}", v); }
template <class T>
std::string num(const std::optional<T>& v) {
  if (!v) return "";
  if constexpr (std::is_floating_point_v<T>) return num(double(*v));
  else return fmt::format("{}", *v);
}

/// The columns every sweep row has after its own leading ones.
const std::vector<std::string>& run_columns() {
  static const std::vector<std::string> c = {
      "status", "wall_s", "parallel_time_s", "ipsc2_time_s", "t1_s", "speedup", "efficiency", "estimate_s",
      "efficiency_estimate_charged", "rays", "work_s", "grants",
      "miss_ratio", "cache_miss_ratio", "pages_per_pixel", "communication_rate_bytes_per_s",
      "communication_rate_per_node_bytes_per_s", "ipsc2_rate_per_node_bytes_per_s", "page_requests", "evictions",
      "ray_messages", "spill_fraction", "average_load"};
  return c;
}

/// The columns every sweep row ends with: the settings, and a note (why a
/// point was skipped, or that T_1 ran with more memory).
const std::vector<std::string>& setting_columns() {
  static const std::vector<std::string> c = {"node_memory", "network", "network_scale", "clock", "model_scale",
                                             "width",       "height",  "repeat",        "skip_empty", "note"};
  return c;
}

std::vector<std::string> concat(std::vector<std::string> a, const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

/// Fills a row's run columns from `r`; speedup and efficiency from `t1_s`
/// (<= 0: unknown).
void fill_run(Table& t, std::size_t row, const NodeRun& r, std::uint32_t nodes, double t1_s) {
  if (!r.fits) {
    t.set(row, "status", "skipped");
    t.set(row, "note", r.skipped);
    return;
  }
  t.set(row, "status", "ok");
  t.set(row, "wall_s", num(r.wall_s));
  t.set(row, "parallel_time_s", num(r.parallel_time_s));
  if (t1_s > 0 && r.parallel_time_s > 0) {
    t.set(row, "t1_s", num(t1_s));
    const double speedup = t1_s / r.parallel_time_s;
    t.set(row, "speedup", num(speedup));
    t.set(row, "efficiency", num(speedup / double(nodes)));
    // --submaps balanced: the host's estimate before the run charged to T_p
    // (bench nodes' eff_charged).
    if (r.estimate_s)
      t.set(row, "efficiency_estimate_charged",
            num(charged_efficiency(t1_s, r.parallel_time_s, int(nodes), *r.estimate_s)));
  }
  t.set(row, "estimate_s", num(r.estimate_s));
  t.set(row, "rays", fmt::format("{}", r.rays));
  t.set(row, "work_s", num(r.work_s));
  t.set(row, "grants", num(r.grants));
  t.set(row, "miss_ratio", num(r.miss_ratio));
  t.set(row, "cache_miss_ratio", num(r.cache_miss_ratio));
  t.set(row, "pages_per_pixel", num(r.pages_per_pixel));
  t.set(row, "communication_rate_bytes_per_s", num(r.communication_rate_bytes_per_s));
  if (r.communication_rate_bytes_per_s)
    t.set(row, "communication_rate_per_node_bytes_per_s", num(*r.communication_rate_bytes_per_s / double(nodes)));
  t.set(row, "page_requests", num(r.page_requests));
  t.set(row, "evictions", num(r.evictions));
  t.set(row, "ray_messages", num(r.ray_messages));
  t.set(row, "spill_fraction", num(r.spill_fraction));
  t.set(row, "average_load", num(r.average_load));
  t.set(row, "cache_pages", num(r.cache_pages));
  t.set(row, "pages_total", num(r.pages_total));
  if (r.cache_pages && r.pages_total && *r.pages_total > 0)
    t.set(row, "cache_percent", num(100.0 * double(*r.cache_pages) / double(*r.pages_total)));
}

// --- Options and the common frame of a sweep ---------------------------------

struct SweepOptions {
  core::SceneSource source = tracing_source();
  NodeRunOptions run;
  bool full = false;
  std::string output;  ///< PREFIX; "" = sweep-KIND-SCENE
  bool quiet = false;  ///< -q: no progress lines or notes on stderr
};

/// "rings:4 -t 1": the scene as the paper's tables name the command.
std::string scene_label(const core::SceneSource& s) {
  return s.tessellate > 0 ? fmt::format("{} -t {}", s.spec, s.tessellate) : s.spec;
}

/// "rings4-t1", "teapot8", "model" (for model.nff.gz): a file-name part.
std::string scene_slug(const core::SceneSource& s) {
  std::string base = s.spec;
  if (core::is_scene_file(s.spec)) {
    base = std::filesystem::path(s.spec).filename().string();
    for (const char* ext : {".gz", ".nff"})
      if (base.size() > std::strlen(ext) && base.ends_with(ext)) base.resize(base.size() - std::strlen(ext));
  }
  std::string slug;
  for (char c : base)
    if (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_') slug += c;
  if (slug.empty()) slug = "scene";
  if (s.tessellate > 0) slug += fmt::format("-t{}", s.tessellate);
  return slug;
}

/// Adds SCENE, the machine options, --full and -o to a sweep subcommand.
void add_sweep_options(CLI::App& c, SweepOptions& o, NodeRunOptionSet set) {
  add_scene_options(c, o.source);
  add_camera_options(c, o.source.view);
  add_node_run_options(c, o.run, set);
  CLI::Option* full = c.add_flag("--full", o.full, "The paper's 512x512 image (instead of --width x --height)");
  full->excludes(c.get_option("--width"));
  full->excludes(c.get_option("--height"));
  c.add_flag("--quiet,-q", o.quiet, "No progress lines or notes on stderr (the table still goes to stdout)");
  c.add_option("-o,--output", o.output,
               "Output prefix: writes PREFIX.csv, PREFIX.png and PREFIX.plot.py (default: sweep-KIND-SCENE, e.g. "
               "sweep-nodes-teapot8)");
}

/// What every sweep holds while it runs: the scene's database, the parsed
/// spec and the progress clock.
struct SweepFrame {
  std::string kind;     ///< "nodes", "cache", "page-size"
  std::string scene;    ///< scene_label
  std::string prefix;   ///< output prefix
  core::Database db;
  core::Grid grid;
  NodeRunSpec spec;
  ModelCalibration calibration;  ///< the model clock on this scene (--calibrate)
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
  std::size_t total = 0, done = 0;  ///< runs planned and finished
  bool quiet = false;                ///< -q: no progress lines or notes
  std::unique_ptr<OutputFiles> outputs;  ///< PREFIX.csv (checked before the runs)
  std::size_t csv = 0;                   ///< its index in `outputs`
  const Table* table = nullptr;          ///< the sweep's table, saved to PREFIX.csv after every run

  /// One stderr line after a run: which of how many, the result, elapsed, ETA.
  void progress(const std::string& what, const NodeRun& r, double t1_s, std::uint32_t nodes) {
    ++done;
    const double elapsed = seconds_since(start);
    const double eta = done < total ? elapsed / double(done) * double(total - done) : 0.0;
    std::string result;
    if (!r.fits) {
      result = "skipped (does not fit)";
    } else {
      result = fmt::format("T_p {:.4g} s", r.parallel_time_s);
      if (t1_s > 0 && r.parallel_time_s > 0)
        result += fmt::format(", speedup {:.2f}, efficiency {:.1f}%", t1_s / r.parallel_time_s,
                              100.0 * t1_s / r.parallel_time_s / double(nodes));
      result += fmt::format(" (wall {:.2f} s)", r.wall_s);
    }
    if (!quiet) {
      fmt::print(stderr, "sweep {}: [{}/{}] {}: {}; elapsed {}, ETA {}\n", kind, done, total, what, result,
                 format_duration(elapsed), done < total ? format_duration(eta) : "done");
      std::fflush(stderr);
    }
    // Every finished run is in the CSV at once: an interrupted sweep keeps them.
    if (table && outputs) outputs->update(csv, table->csv_text());
  }
};

SweepFrame make_frame(const std::string& kind, SweepOptions& o, const std::vector<std::string>& modes) {
  if (o.full) o.run.width = o.run.height = 512;
  SweepFrame f;
  f.kind = kind;
  f.quiet = o.quiet;
  f.scene = scene_label(o.source);
  f.prefix = o.output.empty() ? "sweep-" + kind + "-" + scene_slug(o.source) : o.output;
  // Fail before the runs, not after them, when the CSV cannot be written there.
  f.outputs = std::make_unique<OutputFiles>(core::is_scene_file(o.source.spec) ? std::vector<std::string>{o.source.spec}
                                                                              : std::vector<std::string>{});
  f.csv = f.outputs->add(f.prefix + ".csv", "CSV", true);
  f.outputs->add(f.prefix + ".png", "plot", false);  // drawn by the plot script; checked here
  f.spec = make_node_run_spec(o.run);  // before the scene: bad options fail fast
  const core::Scene scene = core::load_scene(o.source);
  f.db = core::make_database(scene);
  core::GridParams gp;
  gp.skip_empty = o.run.skip_empty;
  gp.kind = grid_kind_for(o.run.grid);
  f.grid = core::build_grid(f.db, gp);
  // The model clock checked on this scene once, before every point (--calibrate).
  f.calibration = calibrate_model_clock(f.spec.machine, f.spec.render, f.db, f.grid, o.run.calibrate);
  if (f.calibration.measured && !f.quiet) fmt::print(stderr, "{}\n", f.calibration.summary());
  return f;
}

void fill_settings(Table& t, std::size_t row, const SweepFrame& f, const SweepOptions& o, std::size_t node_memory) {
  t.set(row, "scene", f.scene);
  t.set(row, "node_memory", fmt::format("{}", node_memory));
  t.set(row, "network", f.spec.machine.network.name);
  if (f.spec.machine.network.name == "ipsc2") t.set(row, "network_scale", num(f.spec.machine.network.scale));
  t.set(row, "clock", nodes::compute_clock_name(f.spec.machine.clock));
  if (f.calibration.measured) t.set(row, "model_scale", num(f.calibration.applied ? f.calibration.ratio : 1.0));
  t.set(row, "width", fmt::format("{}", o.run.width));
  t.set(row, "height", fmt::format("{}", o.run.height));
  t.set(row, "repeat", fmt::format("{}", o.run.repeat));
  t.set(row, "page_size", fmt::format("{}", f.spec.page_size));
  t.set(row, "skip_empty", o.run.skip_empty ? "on" : "off");
  // The iPSC/2-equivalent page traffic per node: virtual seconds here are
  // this machine's, the iPSC/2's are 1/scale times longer.
  const std::string& per_node = t.get(row, "communication_rate_per_node_bytes_per_s");
  if (f.spec.machine.network.name == "ipsc2" && !per_node.empty())
    t.set(row, "ipsc2_rate_per_node_bytes_per_s", num(std::stod(per_node) * f.spec.machine.network.scale));
  // T_p as the iPSC/2 would have taken it (Table 3's times).
  const std::string& tp = t.get(row, "parallel_time_s");
  if (f.spec.machine.network.name == "ipsc2" && !tp.empty() && f.spec.machine.network.scale > 0)
    t.set(row, "ipsc2_time_s", num(std::stod(tp) / f.spec.machine.network.scale));
}

/// Every point's efficiency divides by T_1, so it is the best of at least
/// this many runs (a one-node run is cheap beside the others).
constexpr int kT1MinRepeat = 3;

/// Runs T_1 (one node) for `mode`, best of max(kT1MinRepeat, --repeat);
/// when it does not fit --node-memory, again with kT1FallbackMemory. `note`
/// gets what happened.
/// The svm T_1 row of a cache or page-size sweep (one node, all pages
/// home); returns its index.
std::size_t add_svm_t1_row(Table& t, const SweepFrame& f, const SweepOptions& o, const NodeRun& t1_run, double t1,
                           const std::string& note) {
  const std::size_t row = t.add_row();
  t.set(row, "role", "T_1");
  t.set(row, "mode", "svm");
  t.set(row, "nodes", "1");
  t.set(row, "cache", "all pages home");
  fill_run(t, row, t1_run, 1, t1);
  t.set(row, "cache_percent", "");
  if (!note.empty()) t.set(row, "note", note);
  fill_settings(t, row, f, o, t1_run.node_memory);
  t.set(row, "repeat", fmt::format("{}", std::max(o.run.repeat, kT1MinRepeat)));
  return row;
}

/// A sweep point's row: svm on `o.nodes` nodes with cache `cache_label`.
std::size_t add_svm_point_row(Table& t, const SweepFrame& f, const SweepOptions& o, std::uint32_t nodes,
                              const NodeRun& r, const std::string& cache_label, double t1) {
  const std::size_t row = t.add_row();
  t.set(row, "role", "point");
  t.set(row, "mode", "svm");
  t.set(row, "nodes", fmt::format("{}", nodes));
  t.set(row, "cache", cache_label);
  fill_run(t, row, r, nodes, t1);
  fill_settings(t, row, f, o, r.node_memory);
  return row;
}

NodeRun run_t1(SweepFrame& f, const std::string& mode, NodeRunSpec spec, std::string& note) {
  spec.repeat = std::max(spec.repeat, kT1MinRepeat);
  NodeRun r = run_best(f.db, f.grid, mode, spec, 1);
  if (r.fits) return r;
  const std::string why = r.skipped;
  const std::size_t fallback = t1_fallback_memory();
  r = run_best(f.db, f.grid, mode, spec, 1, fallback);
  note = fmt::format("T_1 ran with --node-memory {} because one {} node cannot hold it ({})",
                     nodes::format_bytes(fallback), nodes::format_bytes(spec.machine.node_memory), why);
  if (!f.quiet)
    fmt::print(stderr, "sweep {}: note: {} T_1 runs with {} of node memory: {}\n", f.kind, mode,
               nodes::format_bytes(fallback), why);
  return r;
}

/// Writes the CSV, runs the plot script, prints where things went.
void finish(const SweepFrame& f, const Table& t, const std::string& title) {
  const std::string csv = f.prefix + ".csv", png = f.prefix + ".png", script = f.prefix + ".plot.py";
  f.outputs->text(f.csv, t.csv_text());
  f.outputs->commit();
  const PlotOutcome plot = run_plot_script(sweep_plot_script(), script, {csv, png, f.kind, title});
  fmt::print("\nsweep {} took {}; wrote {}", f.kind, format_duration(seconds_since(f.start)), csv);
  if (plot.ran) {
    fmt::print(", {} (plotted by {})\n", png, script);
  } else {
    fmt::print("\nplot: not drawn: {}\nto plot it later: {}\n", plot.message, plot.command);
  }
}

/// Throws UsageError when no row ran within --node-memory.
void require_some_fit(const Table& t, const SweepFrame& f, const std::string& first_skip) {
  for (std::size_t r = 0; r < t.size(); ++r)
    if (t.get(r, "status") == "ok" && t.get(r, "role") != "T_1" &&
        t.get(r, "note").find("T_1 ran with") == std::string::npos)
      return;
  throw UsageError(fmt::format("sweep {}: no point fits a node's memory ({}); use {}", f.kind,
                               first_skip.empty() ? "no run" : first_skip,
                               f.kind == "nodes" ? "more --node-memory, more --nodes or a smaller scene"
                                                 : "more --nodes, more --node-memory or a smaller cache"));
}

std::string title_of(const SweepFrame& f, const SweepOptions& o, const std::string& what) {
  return fmt::format("raynode sweep {}: {}, {}x{}, {}network {}, node memory {}, clock {}, {} grid", f.kind, f.scene,
                     o.run.width, o.run.height, what, f.spec.machine.network.name, o.run.node_memory,
                     nodes::compute_clock_name(f.spec.machine.clock), core::grid_kind_name(f.grid.kind()));
}

// --- sweep nodes ---------------------------------------------------------------

struct NodesSweepOptions : SweepOptions {
  std::string modes = "svm,dataflow,replicated";
  std::string nodes = "1,2,4,8,16,32,64";
};

std::vector<std::string> parse_modes(const std::string& text) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t comma = std::min(text.find(',', start), text.size());
    std::string m = text.substr(start, comma - start);
    start = comma + 1;
    m.erase(0, m.find_first_not_of(" \t"));
    m.erase(m.find_last_not_of(" \t") + 1);
    if (m.empty()) continue;
    if (m != "svm" && m != "dataflow" && m != "replicated")
      throw UsageError("--modes: unknown mode '" + m + "' (svm, dataflow, replicated)");
    if (std::find(out.begin(), out.end(), m) == out.end()) out.push_back(m);
  }
  if (out.empty()) throw UsageError("--modes: the list is empty (e.g. svm,dataflow,replicated)");
  return out;
}

void run_sweep_nodes(NodesSweepOptions& o) {
  const std::vector<std::string> modes = parse_modes(o.modes);
  std::vector<std::uint32_t> counts = parse_node_list(o.nodes);
  if (counts.front() != 1) {
    counts.insert(counts.begin(), 1);
    if (!o.quiet) fmt::print(stderr, "sweep nodes: note: added 1 to --nodes: T_1 is each mode's own one-node run\n");
  }
  SweepFrame f = make_frame("nodes", o, modes);
  f.total = modes.size() * counts.size();
  Table t(concat(concat({"scene", "mode", "nodes"}, run_columns()), concat({"page_size"}, setting_columns())));
  f.table = &t;  // saved to PREFIX.csv after every run
  std::string first_skip;
  for (const std::string& mode : modes) {
    double t1 = 0;
    for (std::uint32_t n : counts) {
      std::string note;
      const NodeRun r = n == 1 ? run_t1(f, mode, f.spec, note) : run_best(f.db, f.grid, mode, f.spec, n);
      if (n == 1 && r.fits) t1 = r.parallel_time_s;
      if (!r.fits && first_skip.empty()) first_skip = r.skipped;
      const std::size_t row = t.add_row();
      t.set(row, "mode", mode);
      t.set(row, "nodes", fmt::format("{}", n));
      fill_run(t, row, r, n, t1);
      if (!note.empty()) t.set(row, "note", note);
      fill_settings(t, row, f, o, r.node_memory);
      if (n == 1) t.set(row, "repeat", fmt::format("{}", std::max(o.run.repeat, kT1MinRepeat)));
      if (mode != "svm") t.set(row, "page_size", "");
      f.progress(fmt::format("{} {} node{}", mode, n, n == 1 ? "" : "s"), r, t1, n);
    }
  }
  require_some_fit(t, f, first_skip);
  fmt::print("{}\n", title_of(f, o, ""));
  t.print({"mode", "nodes", "status", "wall_s", "parallel_time_s", "speedup", "efficiency", "rays", "grants",
           "miss_ratio", "pages_per_pixel", "communication_rate_bytes_per_s", "page_requests", "ray_messages",
           "spill_fraction", "average_load"},
          {"mode", "nodes", "status", "wall_s", "T_p_s", "speedup", "efficiency", "rays", "grants", "miss_ratio",
           "pages/px", "comm_B/s", "page_reqs", "ray_msgs", "spill", "avg_load"});
  for (std::size_t r = 0; r < t.size(); ++r)
    if (!t.get(r, "note").empty())
      fmt::print("note: {} {} nodes: {}\n", t.get(r, "mode"), t.get(r, "nodes"), t.get(r, "note"));
  finish(f, t, title_of(f, o, ""));
}

// --- sweep cache ---------------------------------------------------------------

NodeRunSpec with_cache(NodeRunSpec spec, const CachePoint& p) {
  spec.cache_fraction = p.fraction;
  spec.cache_pages = p.pages;
  return spec;
}

struct CacheSweepOptions : SweepOptions {
  std::uint32_t nodes = 32;
  std::string cache = "1p,1..100%,max";  // from one page, as the paper's Figures 8-10
};

void run_sweep_cache(CacheSweepOptions& o) {
  const std::vector<CachePoint> points = parse_cache_points(o.cache);
  SweepFrame f = make_frame("cache", o, {"svm"});
  f.total = points.size() + 1;
  Table t(concat(concat({"scene", "role", "mode", "nodes", "page_size", "cache", "cache_pages", "cache_percent",
                         "pages_total"},
                        run_columns()),
                 setting_columns()));
  f.table = &t;  // saved to PREFIX.csv after every run
  std::string note;
  NodeRunSpec t1_spec = f.spec;  // no cache limit: all pages are home on one node
  const NodeRun t1_run = run_t1(f, "svm", t1_spec, note);
  const double t1 = t1_run.fits ? t1_run.parallel_time_s : 0;
  {
    add_svm_t1_row(t, f, o, t1_run, t1, note);
    f.progress("T_1: svm 1 node, all pages home", t1_run, t1, 1);
  }
  std::string first_skip;
  for (const CachePoint& p : points) {
    const NodeRun r = run_best(f.db, f.grid, "svm", with_cache(f.spec, p), o.nodes);
    if (!r.fits && first_skip.empty()) first_skip = r.skipped;
    const std::size_t row = add_svm_point_row(t, f, o, o.nodes, r, p.label, t1);
    if (!r.fits && p.fraction > 0) t.set(row, "cache_percent", num(100.0 * p.fraction));
    f.progress(fmt::format("svm {} nodes, cache {}", o.nodes, p.label), r, t1, o.nodes);
  }
  require_some_fit(t, f, first_skip);
  const std::string what = fmt::format("svm {} nodes, page size {} B, ", o.nodes, f.spec.page_size);
  fmt::print("{}\n", title_of(f, o, what));
  t.print({"role", "nodes", "cache", "cache_pages", "cache_percent", "status", "wall_s", "parallel_time_s",
           "speedup", "efficiency", "miss_ratio", "cache_miss_ratio", "pages_per_pixel",
           "communication_rate_bytes_per_s", "ipsc2_rate_per_node_bytes_per_s", "evictions"},
          {"role", "nodes", "cache", "pages", "cache_%", "status", "wall_s", "T_p_s", "speedup", "efficiency",
           "miss_ratio", "cache_miss", "pages/px", "comm_B/s", "iPSC2_B/s/node", "evictions"});
  for (std::size_t r = 0; r < t.size(); ++r)
    if (!t.get(r, "note").empty()) fmt::print("note: cache {}: {}\n", t.get(r, "cache"), t.get(r, "note"));
  finish(f, t, title_of(f, o, what));
}

// --- sweep page-size -------------------------------------------------------------

struct PageSizeSweepOptions : SweepOptions {
  std::uint32_t nodes = 32;
  std::string page_sizes = "256,512,1024,2048,4096";
  std::string cache;  ///< one cache point; "" = all free memory
};

void run_sweep_page_size(PageSizeSweepOptions& o) {
  const std::vector<std::uint32_t> sizes = parse_count_list(o.page_sizes, "--page-size", 64, 1u << 24);
  for (std::uint32_t s : sizes)
    if ((s & (s - 1)) != 0) throw UsageError(fmt::format("--page-size: {} is not a power of two", s));
  CachePoint cache;
  cache.max = true;
  cache.label = "max";
  if (!o.cache.empty()) {
    const std::vector<CachePoint> c = parse_cache_points(o.cache);
    if (c.size() != 1) throw UsageError("--cache: sweep page-size takes one cache size, got '" + o.cache + "'");
    cache = c.front();
  }
  SweepFrame f = make_frame("page-size", o, {"svm"});
  f.total = 2 * sizes.size();
  Table t(concat(concat({"scene", "role", "mode", "nodes", "page_size", "cache", "cache_pages", "cache_percent",
                         "pages_total"},
                        run_columns()),
                 setting_columns()));
  f.table = &t;  // saved to PREFIX.csv after every run
  std::string first_skip;
  for (std::uint32_t ps : sizes) {
    NodeRunSpec spec = f.spec;
    spec.page_size = ps;
    std::string note;
    const NodeRun t1_run = run_t1(f, "svm", spec, note);
    const double t1 = t1_run.fits ? t1_run.parallel_time_s : 0;
    std::size_t row = add_svm_t1_row(t, f, o, t1_run, t1, note);
    t.set(row, "page_size", fmt::format("{}", ps));
    f.progress(fmt::format("T_1: svm 1 node, page size {} B", ps), t1_run, t1, 1);

    const NodeRun r = run_best(f.db, f.grid, "svm", with_cache(spec, cache), o.nodes);
    if (!r.fits && first_skip.empty()) first_skip = r.skipped;
    row = add_svm_point_row(t, f, o, o.nodes, r, cache.label, t1);
    t.set(row, "page_size", fmt::format("{}", ps));
    f.progress(fmt::format("svm {} nodes, page size {} B", o.nodes, ps), r, t1, o.nodes);
  }
  require_some_fit(t, f, first_skip);
  const std::string what = fmt::format("svm {} nodes, cache {}, ", o.nodes, cache.label);
  fmt::print("{}\n", title_of(f, o, what));
  t.print({"role", "nodes", "page_size", "pages_total", "cache_pages", "status", "wall_s", "parallel_time_s",
           "speedup", "efficiency", "miss_ratio", "cache_miss_ratio", "pages_per_pixel",
           "communication_rate_bytes_per_s", "ipsc2_rate_per_node_bytes_per_s", "page_requests"},
          {"role", "nodes", "page_B", "pages", "cache_pages", "status", "wall_s", "T_p_s", "speedup", "efficiency",
           "miss_ratio", "cache_miss", "pages/px", "comm_B/s", "iPSC2_B/s/node", "page_reqs"});
  for (std::size_t r = 0; r < t.size(); ++r)
    if (!t.get(r, "note").empty()) fmt::print("note: page size {}: {}\n", t.get(r, "page_size"), t.get(r, "note"));
  finish(f, t, title_of(f, o, what));
}

constexpr const char* kCommonFooter =
    "Output: PREFIX.csv (one row per run; empty cells where a mode has no such counter; status 'skipped' with the\n"
    "reason in 'note' for a point that does not fit a node's memory), PREFIX.png (plotted by the embedded\n"
    "PREFIX.plot.py with /usr/bin/python3 or python3 and matplotlib; without them the CSV stays and the command\n"
    "to plot it later is printed). One progress line per run on stderr, the table on stdout.\n"
    "Times are virtual (the emulated machine's clocks, --network and --clock); speedup = T_1 / T_p,\n"
    "efficiency = speedup / nodes (the paper's definitions); T_1 is the best of max(3, --repeat) one-node runs.\n"
    "A T_1 run whose database does not fit one node's --node-memory runs with the budget raised (accounting\n"
    "only) and the row says so. Under --clock cpu virtual times follow the host's load: on a busy host use\n"
    "--repeat or --clock model.\n"
    "Exit status: 0 ok; 1 unreadable scene or failed run; 2 bad option or nothing fits.";

}  // namespace

void register_sweep_commands(CLI::App& app) {
  CLI::App* sweep = app.add_subcommand("sweep", "The paper's experiments: speedup and efficiency against nodes, "
                                                "cache size or page size (CSV + PNG plot)");
  sweep->require_subcommand(1);

  auto no = std::make_shared<NodesSweepOptions>();
  CLI::App* n = sweep->add_subcommand(
      "nodes", "Speedup and efficiency against the node count, one curve per mode (the paper's Figures 5 and 7)");
  add_sweep_options(*n, *no, {});
  n->add_option("--modes", no->modes, "Node modes, comma-separated: svm, dataflow, replicated")
      ->capture_default_str();
  n->add_option("--nodes", no->nodes,
                "Node counts: a list (1,2,4,8) or a range of powers of two (1..64), mixed freely; 1 is added when "
                "missing (T_1 = each mode's one-node run)")
      ->capture_default_str();
  n->footer(std::string("Example: raynode sweep nodes teapot:8 --modes svm,dataflow --nodes 1..64 --network ipsc2\n") +
            kCommonFooter);
  n->callback([no, n] {
    check_mode_options(*n, parse_modes(no->modes));
    run_sweep_nodes(*no);
  });

  auto co = std::make_shared<CacheSweepOptions>();
  CLI::App* c = sweep->add_subcommand(
      "cache", "svm: efficiency, miss ratio and communication rate against the page cache size (the paper's "
               "Figures 8, 9, 10)");
  add_sweep_options(*c, *co, {.page_size = true, .dataflow = false});
  c->add_option("--nodes", co->nodes, "Nodes (the paper: 32)")->check(CLI::Range(2u, nodes::kMaxNodes))
      ->capture_default_str();
  c->add_option("--cache", co->cache,
                "Cache sizes per node, comma-separated. A number is a percentage of the database's pages (the '%' "
                "is optional); 'A..B%' = the 1-2-5 series between A and B plus both ends (1..100% = 1,2,5,10,20,"
                "50,100); 'A..B:N%' = N evenly spaced values from A to B; 'Np' = N pages; 'max' = all the memory a "
                "node has left after its home pages (svm's default, the paper's right end). The default starts at "
                "one page, as the paper's plots do. A size that does not fit --node-memory is reported as skipped")
      ->capture_default_str();
  c->footer(std::string("Examples (the paper's Figures 8-10): raynode sweep cache rings:4 -t 1;  raynode sweep "
                        "cache tetra:9 --cache 0.1..10%,max\n") +
            kCommonFooter);
  c->callback([co, c] {
    check_mode_options(*c, {"svm"});
    run_sweep_cache(*co);
  });

  auto po = std::make_shared<PageSizeSweepOptions>();
  CLI::App* p = sweep->add_subcommand(
      "page-size", "svm: efficiency, miss ratio, pages per pixel and communication rate against the page size");
  add_sweep_options(*p, *po, {.page_size = false, .dataflow = false});
  p->add_option("--nodes", po->nodes, "Nodes")->check(CLI::Range(2u, nodes::kMaxNodes))->capture_default_str();
  p->add_option("--page-size", po->page_sizes,
                "Page sizes in bytes, powers of two >= 64: a list or a range of powers of two (256..4096)")
      ->capture_default_str();
  p->add_option("--cache", po->cache,
                "One cache size per node as in 'sweep cache' (default: max, all the memory a node has left)");
  p->footer(std::string("T_1 is the one-node run at each page size.\nExample: raynode sweep page-size rings:4 -t 1\n") +
            kCommonFooter);
  p->callback([po, p] {
    check_mode_options(*p, {"svm"});
    run_sweep_page_size(*po);
  });
}

}  // namespace raynode::apps
