// `raynode bench mailbox` and `raynode bench nodes`: benchmarks of the node
// emulator (nodes/). Timings only; nothing here is a pass/fail check.
//
//  * bench mailbox: raw Mailbox throughput with P producer threads and one
//    blocking consumer (messages/s), and the round-trip latency of a
//    ping-pong between two emulated nodes through NodeContext (futex waits).
//  * bench nodes SCENE: renders SCENE in replicated, svm or dataflow mode
//    (--mode) for each node count (apps/node_runs.h, shared with `raynode
//    sweep`) and prints wall time, virtual parallel time T_p, speedup
//    T_1 / T_p and efficiency (the paper's definitions, T_1 = the one-node
//    run), with svm's miss ratio and pages per pixel or dataflow's ray
//    messages, spill fraction and average load; and the sequential tracer's
//    wall and CPU time on the same image (best of --repeat), the reference a
//    one-node run is compared with: under --clock cpu it prints the one-node
//    run's busy CPU time over sequential's (svm's "within 10%" figure).
#include <fmt/core.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>
#include <vector>

#include "apps/commands.h"
#include "apps/run_info.h"
#include "apps/sweep_points.h"
#include "apps/output_files.h"
#include "apps/node_runs.h"
#include "core/cell_blocks.h"
#include "core/database.h"
#include "core/direct_view.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/scene_source.h"
#include "nodes/cpu_time.h"
#include "nodes/machine.h"
#include "nodes/mailbox.h"

namespace raynode::apps {

namespace {

/// Messages per second from `producers` threads into one mailbox.
double mailbox_throughput(std::uint32_t producers, std::uint64_t per_producer, std::uint32_t payload) {
  nodes::Arena arena(0, std::size_t(1) << 30);
  nodes::Mailbox box(arena, 1024, payload);
  std::atomic<bool> stop{false};
  std::vector<std::byte> data(payload, std::byte{7});
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<std::thread> threads;
  for (std::uint32_t p = 0; p < producers; ++p)
    threads.emplace_back([&] {
      const std::span<const std::byte> parts[1] = {data};
      nodes::MessageHeader h;
      for (std::uint64_t i = 0; i < per_producer; ++i)
        while (!box.try_push(h, parts)) std::this_thread::yield();
    });
  std::vector<std::byte> buf(payload);
  nodes::MessageHeader h;
  for (std::uint64_t got = 0, total = per_producer * producers; got < total;) {
    if (box.try_pop(h, buf.data())) ++got;
    else box.wait(stop);
  }
  for (auto& t : threads) t.join();
  return double(per_producer * producers) / seconds_since(t0);
}

/// Microseconds per round trip between two nodes of an emulated machine.
struct NodesBenchOptions {
  core::SceneSource source = tracing_source();
  std::string nodes = "1,2,4,8,16,32,64";  ///< --nodes: a list, "1,2,4" or "1..64" (parse_node_list)
  NodeRunOptions run = [] {
    NodeRunOptions r;  // the paper's 512x512 image; the machine's defaults are every command's
    r.width = r.height = 512;
    return r;
  }();
  std::string json_path;
  std::string mode = "replicated";
  std::uint32_t pack_min = 0;  ///< svm and the sequential reference: --pack-cells (off unless asked)
};

/// The sequential tracer on the bench's image: what a one-node run is
/// compared with, the best of --repeat. The same cells as the nodes walk
/// (object lists, or with --pack-cells the same packed blocks); its thread
/// CPU time is what a node's CPU clock counts as busy time. With `pairs` (1
/// in --nodes), its runs and the one-node runs take turns (sequential, one
/// node, sequential, ...), so that a change in the machine's speed during
/// the bench (a VM's moves by 10-25%) reaches both sides of the ratio alike;
/// each side keeps its best, and every pair's ratio is kept for their
/// median (CPU clock only: under the model clock a node's time is modelled).
struct SequentialReference {
  double wall_s = 0, cpu_s = 0;     ///< the best sequential render's seconds
  std::optional<NodeRun> one_node;  ///< the best one-node run, when `pairs`
  std::vector<double> pair_ratios;  ///< per pair: the node's busy CPU time over sequential's
};

SequentialReference sequential_reference(const NodesBenchOptions& o, const core::Database& db,
                                         const core::Grid& grid, const NodeRunSpec& spec, bool pairs) {
  SequentialReference ref;
  std::optional<core::CellBlocks> blocks;
  if (o.pack_min > 0) blocks = core::build_cell_blocks(db, grid, o.pack_min);
  const core::DirectView view(db, grid, blocks ? &*blocks : nullptr);
  for (int i = 0; i < std::max(1, o.run.repeat); ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = nodes::thread_cpu_seconds();
    (void)core::render_image(view, db, spec.render);
    const double cpu = nodes::thread_cpu_seconds() - c0;
    const double s = seconds_since(t0);
    ref.wall_s = i == 0 ? s : std::min(ref.wall_s, s);
    ref.cpu_s = i == 0 ? cpu : std::min(ref.cpu_s, cpu);
    if (!pairs || (ref.one_node && !ref.one_node->fits)) continue;
    NodeRun r = run_node_mode(db, grid, o.mode, spec, 1);
    if (r.fits && cpu > 0 && o.run.clock == "cpu") ref.pair_ratios.push_back(r.work_s / cpu);
    if (!ref.one_node || !r.fits || r.parallel_time_s < ref.one_node->parallel_time_s) ref.one_node = std::move(r);
  }
  return ref;
}

/// Prints the table's row for the best run `best` of `n` nodes (T_1 = `t1`,
/// 0 if unknown) and returns its JSON row. `ipsc2_scale` > 0 (the ipsc2
/// network's scale) adds T_p as the iPSC/2 would have taken it.
nlohmann::json bench_row(std::FILE* report, std::uint32_t n, const NodeRun& best, double t1, bool flow,
                         bool balanced, double ipsc2_scale) {
  const double tp = best.parallel_time_s;
  const double speedup = t1 > 0 ? t1 / tp : 0;
  const double charged = balanced ? charged_efficiency(t1, tp, n, best.estimate_s.value_or(0)) : 0;
  if (flow)
    fmt::print(report, "{:>6} {:>9.3f} {:>11.5f} {:>9.2f} {:>10.3f} {:>10.4f} {:>10} {:>10.5f} {:>9.3f}", n, best.wall_s,
               tp, speedup, speedup / double(n), best.work_s, best.ray_messages.value_or(0),
               best.spill_fraction.value_or(0), best.average_load.value_or(0));
  else
    fmt::print(report, "{:>6} {:>9.3f} {:>11.5f} {:>9.2f} {:>10.3f} {:>10.4f} {:>8} {:>10.5f} {:>9.2f}{}", n, best.wall_s,
               tp, speedup, speedup / double(n), best.work_s, best.grants.value_or(0), best.miss_ratio.value_or(-1),
               best.pages_per_pixel.value_or(-1), balanced ? fmt::format(" {:>12.3f}", charged) : std::string());
  fmt::print(report, "{}\n", ipsc2_scale > 0 ? fmt::format(" {:>11}", hours_minutes_seconds(tp / ipsc2_scale)) : "");
  nlohmann::json row = {{"nodes", n},       {"wall_s", best.wall_s},         {"parallel_time_s", tp},
                        {"speedup", speedup}, {"efficiency", speedup / double(n)}, {"work_s", best.work_s},
                        {"rays", best.rays}};
  if (flow) {
    row["ray_messages"] = best.ray_messages.value_or(0);
    row["spill_fraction"] = best.spill_fraction.value_or(0);
    row["average_load"] = best.average_load.value_or(0);
  } else {
    row["grants"] = best.grants.value_or(0);
    row["miss_ratio"] = best.miss_ratio.value_or(-1);
    row["pages_per_pixel"] = best.pages_per_pixel.value_or(-1);
    if (best.database_bytes) row["database_bytes"] = *best.database_bytes;  // svm: the shared memory's size
    if (best.accesses) row["accesses"] = *best.accesses;
    if (best.cache_page_accesses) row["cache_page_accesses"] = *best.cache_page_accesses;
  }
  if (ipsc2_scale > 0) row["ipsc2_time_s"] = tp / ipsc2_scale;
  if (balanced) {
    row["estimate_s"] = best.estimate_s.value_or(0);
    row["efficiency_estimate_charged"] = charged;
  }
  if (best.communication_rate_bytes_per_s) {
    row["page_requests"] = best.page_requests.value_or(0);
    row["communication_rate_bytes_per_s"] = *best.communication_rate_bytes_per_s;
  }
  return row;
}

void run_bench_nodes(const NodesBenchOptions& o) {
  if (o.pack_min > 0 && o.mode != "svm")
    throw UsageError("--pack-cells " + std::to_string(o.pack_min) + " is for --mode svm; --mode " + o.mode +
                     " walks the paper's object lists (leave --pack-cells out)");
  const std::vector<std::uint32_t> counts = parse_node_list(o.nodes);
  NodeRunSpec spec = make_node_run_spec(o.run);
  spec.pack_min = o.pack_min;
  // The --json file is checked before the runs ("-" is stdout).
  OutputFiles files(core::is_scene_file(o.source.spec) ? std::vector<std::string>{o.source.spec}
                                                       : std::vector<std::string>{});
  const std::size_t json_out = o.json_path.empty() ? 0 : files.add(o.json_path, "--json file", true);
  std::FILE* report = files.uses_stdout() ? stderr : stdout;  // the table, beside JSON on stdout
  const core::Scene scene = core::load_scene(o.source);
  const core::Database db = core::make_database(scene);
  core::GridParams gp;
  gp.skip_empty = o.run.skip_empty;
  gp.kind = grid_kind_for(o.run.grid);
  const core::Grid grid = core::build_grid(db, core::grid_params_for_packed_cells(gp, o.pack_min));
  // The model clock checked on this scene once, so that T_1 and every T_p use the same unit costs.
  const ModelCalibration calibration = calibrate_model_clock(spec.machine, spec.render, db, grid, o.run.calibrate);
  fmt::print(report, "{} {} {}x{}, network {}, node memory {}, clock {}, submaps {}, work grants {}, requests {}, {}, {} "
             "hardware threads, best of {}\n",
             o.mode, o.source.spec, o.run.width, o.run.height, o.run.network, o.run.node_memory, o.run.clock,
             o.run.submaps, nodes::work_grant_name(nodes::resolved_work_grant(spec.machine)), o.run.work_requests,
             o.pack_min > 0 ? fmt::format("cells of {}+ triangles packed", o.pack_min) : std::string("object lists"),
             std::thread::hardware_concurrency(), o.run.repeat);
  const bool cpu_clock = o.run.clock == "cpu";  // else the node's time is modelled: no ratio to sequential's
  const bool pairs = std::find(counts.begin(), counts.end(), 1u) != counts.end();
  SequentialReference ref = sequential_reference(o, db, grid, spec, pairs);
  const double sequential_s = ref.wall_s, sequential_cpu_s = ref.cpu_s;
  std::optional<NodeRun>& one_node = ref.one_node;
  const std::vector<double>& pair_ratios = ref.pair_ratios;
  fmt::print(report, "sequential render: {:.4f} s wall, {:.4f} s CPU{}\n", sequential_s, sequential_cpu_s,
             one_node ? " (runs taken in turn with the one-node runs)" : "");
  if (calibration.measured) fmt::print(report, "{}\n", calibration.summary());
  const bool flow = o.mode == "dataflow";
  // Balanced submaps: the host's estimate ran before each run, outside
  // virtual time (as the paper leaves out its data-oriented algorithm's);
  // eff_charged adds it to T_p, as serial work of one node before the run.
  const bool balanced = !flow && spec.submaps.rule == control::SubmapRule::kBalanced;
  if (flow)
    fmt::print(report, "{:>6} {:>9} {:>11} {:>9} {:>10} {:>10} {:>10} {:>10} {:>9}", "nodes", "wall_s", "T_p_s", "speedup",
               "efficiency", "work_s", "ray_msgs", "spill", "avg_load");
  else
    fmt::print(report, "{:>6} {:>9} {:>11} {:>9} {:>10} {:>10} {:>8} {:>10} {:>9}{}", "nodes", "wall_s", "T_p_s", "speedup",
               "efficiency", "work_s", "grants", "miss_ratio", "pages/px", balanced ? "  eff_charged" : "");
  // Under the ipsc2 network, T_p as the iPSC/2 would have taken it (its
  // costs are this machine's scaled by network.scale; Table 3's h:m:s).
  const double ipsc2_scale = spec.machine.network.name == "ipsc2" ? spec.machine.network.scale : 0.0;
  fmt::print(report, "{}\n", ipsc2_scale > 0 ? fmt::format(" {:>11}", "ipsc2_time") : "");
  nlohmann::json rows = nlohmann::json::array();
  double t1 = 0, t1_work_s = 0;  // the one-node run's T_p and busy time
  std::optional<double> one_node_ratio, one_node_median;  // set after the rows
  // The --json document; written after every row, so an interrupted bench keeps the rows it finished.
  auto json_doc = [&] {
    return nlohmann::json{{"scene", o.source.spec},       {"mode", o.mode},   {"network", o.run.network},
                          {"clock", o.run.clock},         {"width", o.run.width}, {"height", o.run.height},
                          {"submaps", o.run.submaps},     {"work_grants", nodes::work_grant_name(nodes::resolved_work_grant(spec.machine))},
                          {"work_requests", o.run.work_requests}, {"pack_cells", o.pack_min},
                          {"grid", grid_json(grid)},
                          {"primitives", db.primitives.size()},
                          {"vertex_normal_sets", db.vertex_normals.size()},
                          {"node_memory", o.run.node_memory},
                          {"shadow_rays", o.run.shadow_rays},
                          {"sequential_s", sequential_s}, {"sequential_cpu_s", sequential_cpu_s},
                          {"one_node_over_sequential",
                           one_node_ratio ? nlohmann::json(*one_node_ratio) : nlohmann::json()},
                          {"one_node_over_sequential_median",
                           one_node_median ? nlohmann::json(*one_node_median) : nlohmann::json()},
                          {"one_node_pair_ratios", pair_ratios},
                          {"model_calibration", calibration.to_json()},
                          {"rows", rows},
                          {"run", run_json()}}
        .dump(2) +
        "\n";
  };
  for (const std::uint32_t n : counts) {
    const NodeRun best = n == 1 && one_node ? *one_node : run_best(db, grid, o.mode, spec, std::uint32_t(n));
    if (!best.fits) {
      fmt::print(report, "{:>6} skipped: {}\n", n, best.skipped);
      rows.push_back({{"nodes", n}, {"skipped", best.skipped}});
      continue;
    }
    if (n == 1) {
      t1 = best.parallel_time_s;
      t1_work_s = best.work_s;
    }
    rows.push_back(bench_row(report, n, best, t1, flow, balanced, ipsc2_scale));
    if (!o.json_path.empty()) files.update(json_out, json_doc());
  }
  if (t1 == 0) fmt::print(report, "(no 1-node run in --nodes: speedup needs T_1)\n");
  if (balanced)
    fmt::print(report, "eff_charged: T_1 / (N x (T_p + the host's load estimate)), the estimate that cut the balanced submaps "
               "(one pixel per {0}x{0} block, traced before the run, outside virtual time) counted as serial work; "
               "one node traces none\n",
               o.run.subsample);
  // One node against sequential (the svm issue's "within 10%"): the node's
  // busy CPU time over sequential's, each the best of --repeat, and the
  // median of the pairs' ratios. Under the model clock the node's time is
  // modelled, not measured: no ratio.
  if (t1 > 0 && cpu_clock && sequential_cpu_s > 0) {
    one_node_ratio = t1_work_s / sequential_cpu_s;
    if (!pair_ratios.empty()) one_node_median = median(pair_ratios);
    fmt::print(report, "one node against sequential: {:.3f}x (the node's busy CPU time over sequential's, best of {} each, "
               "taken in turn; median of the {} pairs' ratios {:.3f}x)\n",
               *one_node_ratio, std::max(1, o.run.repeat), pair_ratios.size(), one_node_median.value_or(0));
  }
  if (!o.json_path.empty()) {
    files.text(json_out, json_doc());
    files.commit();
  }
}

}  // namespace

void register_bench_nodes_commands(CLI::App& app) {
  CLI::App* bench = app.get_subcommand("bench");

  struct MailboxOptions {
    std::uint64_t messages = 2000000;
    std::uint64_t trips = 20000;
  };
  auto mo = std::make_shared<MailboxOptions>();
  CLI::App* m = bench->add_subcommand("mailbox", "Node emulator: mailbox messages/s and node-to-node round trip");
  m->add_option("--messages", mo->messages, "Messages per throughput run")->capture_default_str();
  m->add_option("--trips", mo->trips, "Round trips of the ping-pong")->capture_default_str();
  m->callback([mo] {
    for (std::uint32_t producers : {1u, 4u})
      for (std::uint32_t payload : {16u, 1024u})
        fmt::print("mailbox: {} producer(s), {:>4} B payload: {:>12.0f} messages/s\n", producers, payload,
                   mailbox_throughput(producers, mo->messages / producers, payload));
    fmt::print("round trip between two nodes (send + blocking receive, both ways): {:.2f} us\n",
               [&] {
                 nodes::MachineParams p;
                 p.nodes = 2;
                 p.timeout_s = 120;
                 return 1e6 * node_round_trip_s(p, sizeof(std::uint64_t), mo->trips);
               }());
  });

  auto no = std::make_shared<NodesBenchOptions>();
  CLI::App* c = bench->add_subcommand("nodes", "Node emulator: replicated-, svm- or dataflow-mode render for several "
                                               "node counts (wall time, virtual T_p, speedup, efficiency)");
  add_scene_options(*c, no->source);
  add_camera_options(*c, no->source.view);
  c->add_option("--nodes", no->nodes,
                "Node counts: a comma-separated list and/or ranges of powers of two (1,2,4 or 1..64; include 1 "
                "for T_1)")
      ->capture_default_str();
  add_node_run_options(*c, no->run, {.experiment = true, .page_size = true, .cache = true, .dataflow = true});
  add_json_option(*c, no->json_path, "The table (also printed as text unless the JSON goes to stdout)");
  c->add_option("--mode", no->mode, "Node mode: replicated, svm or dataflow")
      ->check(CLI::IsMember({"replicated", "svm", "dataflow"}))
      ->capture_default_str();
  add_pack_cells_option(*c, no->pack_min);
  c->callback([no, c] {
    check_mode_options(*c, {no->mode});
    run_bench_nodes(*no);
  });
}

}  // namespace raynode::apps
