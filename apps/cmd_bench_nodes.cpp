// `raynode bench mailbox` and `raynode bench nodes`: benchmarks of the node
// emulator (nodes/). Timings only; nothing here is a pass/fail check.
//
//  * bench mailbox: raw Mailbox throughput with P producer threads and one
//    blocking consumer (messages/s), and the round-trip latency of a
//    ping-pong between two emulated nodes through NodeContext (futex waits).
//  * bench nodes SCENE: renders SCENE in replicated or svm mode (--mode) for
//    each node count and prints wall time, virtual parallel time T_p,
//    speedup T_1 / T_p and efficiency (the paper's definitions, T_1 = the
//    one-node run), with svm's miss ratio and pages per pixel; and the
//    sequential tracer's time on the same image (best of --repeat), the
//    reference a one-node run is compared with.
#include <fmt/core.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>
#include <vector>

#include "apps/commands.h"
#include "core/database.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/scene_source.h"
#include "nodes/machine.h"
#include "nodes/mailbox.h"
#include "nodes/replicated.h"
#include "svm/svm.h"

namespace raynode::apps {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

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
double round_trip_us(std::uint64_t trips) {
  nodes::MachineParams p;
  p.nodes = 2;
  p.timeout_s = 120;
  nodes::Machine machine(p);
  double seconds = 0;
  machine.run(
      [&](nodes::NodeContext& ctx) {
        const nodes::NodeId other = 1 - ctx.id();
        const std::uint64_t token = 0;
        const auto t0 = std::chrono::steady_clock::now();
        for (std::uint64_t i = 0; i < trips; ++i) {
          if (ctx.id() == 0) {
            ctx.send(other, nodes::MessageType::kTest, token);
            ctx.receive(nodes::WaitKind::kIdle);
          } else {
            ctx.receive(nodes::WaitKind::kIdle);
            ctx.send(other, nodes::MessageType::kTest, token);
          }
        }
        if (ctx.id() == 0) seconds = seconds_since(t0);
      },
      [](nodes::NodeContext&) {});
  return 1e6 * seconds / double(trips);
}

struct NodesBenchOptions {
  core::SceneSource source;
  std::vector<int> nodes{1, 2, 4, 8, 16, 32, 64};
  int width = 512, height = 512;
  std::string node_memory = "16MiB";
  std::string network = "none";
  double schedule_window_us = 200;
  std::string json_path;
  std::string mode = "replicated";
  std::uint32_t page_size = 1024;
  std::uint32_t cache_pages = 0;
  int repeat = 1;
};

/// One node-mode run: T_p and the counters the table prints.
struct NodesRun {
  double wall_s = 0, parallel_time_s = 0, work_s = 0;
  std::uint64_t grants = 0;
  double miss_ratio = -1, pages_per_pixel = -1;  ///< svm only
};

NodesRun run_nodes_once(const NodesBenchOptions& o, const core::Database& db, const core::Grid& grid, int n,
                        const nodes::NetworkModel& network) {
  nodes::MachineParams mp;
  mp.nodes = std::uint32_t(n);
  mp.node_memory = nodes::parse_bytes(o.node_memory);
  mp.network = network;
  mp.schedule_window_s = o.schedule_window_us * 1e-6;
  core::RenderParams rp;
  rp.width = o.width;
  rp.height = o.height;
  NodesRun out;
  const auto t0 = std::chrono::steady_clock::now();
  const nodes::RunReport* run = nullptr;
  const std::vector<nodes::WorkStats>* work = nullptr;
  nodes::ReplicatedResult rr;
  svm::SvmResult sr;
  if (o.mode == "svm") {
    svm::SvmParams p;
    p.render = rp;
    p.machine = mp;
    p.page_size = o.page_size;
    p.cache_pages = o.cache_pages;
    sr = svm::render_svm(db, grid, p);
    run = &sr.run;
    work = &sr.work;
    const svm::PagerStats t = sr.pager_total();
    out.miss_ratio = t.miss_ratio();
    out.pages_per_pixel = t.pages_per_pixel();
  } else {
    nodes::ReplicatedParams p;
    p.render = rp;
    p.machine = mp;
    rr = nodes::render_replicated(db, grid, p);
    run = &rr.run;
    work = &rr.work;
  }
  out.wall_s = seconds_since(t0);
  out.parallel_time_s = run->parallel_time_s;
  for (const auto& nr : run->nodes) out.work_s += nr.counters.busy_s;
  for (const auto& w : *work) out.grants += w.grants_given;
  return out;
}

void run_bench_nodes(const NodesBenchOptions& o) {
  const core::Scene scene = core::load_scene(o.source);
  const core::Database db = core::make_database(scene);
  const core::Grid grid = core::build_grid(db);
  fmt::print("{} {} {}x{}, network {}, node memory {}, {} hardware threads, best of {}\n", o.mode, o.source.spec,
             o.width, o.height, o.network, o.node_memory, std::thread::hardware_concurrency(), o.repeat);
  // The sequential tracer on the same image: what a one-node run is compared with.
  double sequential_s = 0;
  {
    core::RenderParams rp;
    rp.width = o.width;
    rp.height = o.height;
    const core::DirectView view(db, grid);
    for (int i = 0; i < o.repeat; ++i) {
      const auto t0 = std::chrono::steady_clock::now();
      (void)core::render_image(view, db, rp);
      const double s = seconds_since(t0);
      sequential_s = i == 0 ? s : std::min(sequential_s, s);
    }
  }
  fmt::print("sequential render: {:.4f} s\n", sequential_s);
  fmt::print("{:>6} {:>9} {:>11} {:>9} {:>10} {:>10} {:>8} {:>10} {:>9}\n", "nodes", "wall_s", "T_p_s", "speedup",
             "efficiency", "work_s", "grants", "miss_ratio", "pages/px");
  nlohmann::json rows = nlohmann::json::array();
  double t1 = 0;
  const nodes::NetworkModel network = nodes::make_network(o.network);
  for (int n : o.nodes) {
    NodesRun best;
    for (int i = 0; i < o.repeat; ++i) {
      const NodesRun r = run_nodes_once(o, db, grid, n, network);
      if (i == 0 || r.parallel_time_s < best.parallel_time_s) best = r;
    }
    const double tp = best.parallel_time_s;
    if (n == 1) t1 = tp;
    const double speedup = t1 > 0 ? t1 / tp : 0;
    fmt::print("{:>6} {:>9.3f} {:>11.5f} {:>9.2f} {:>10.3f} {:>10.4f} {:>8} {:>10.5f} {:>9.2f}\n", n, best.wall_s, tp,
               speedup, speedup / double(n), best.work_s, best.grants, best.miss_ratio, best.pages_per_pixel);
    rows.push_back({{"nodes", n},
                    {"wall_s", best.wall_s},
                    {"parallel_time_s", tp},
                    {"speedup", speedup},
                    {"efficiency", speedup / double(n)},
                    {"work_s", best.work_s},
                    {"grants", best.grants},
                    {"miss_ratio", best.miss_ratio},
                    {"pages_per_pixel", best.pages_per_pixel}});
  }
  if (t1 == 0) fmt::print("(no 1-node run in --nodes: speedup needs T_1)\n");
  if (!o.json_path.empty()) {
    std::ofstream f(o.json_path);
    f << nlohmann::json{{"scene", o.source.spec}, {"mode", o.mode},        {"network", o.network},
                        {"sequential_s", sequential_s}, {"rows", rows}}
             .dump(2)
      << "\n";
    if (!f) throw std::runtime_error("cannot write " + o.json_path);
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
               round_trip_us(mo->trips));
  });

  auto no = std::make_shared<NodesBenchOptions>();
  CLI::App* c = bench->add_subcommand("nodes", "Node emulator: replicated- or svm-mode render for several node "
                                               "counts (wall time, virtual T_p, speedup, efficiency)");
  add_scene_options(*c, no->source);
  c->add_option("--nodes", no->nodes, "Node counts, comma-separated (include 1 for T_1)")
      ->delimiter(',')
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  c->add_option("--width", no->width, "Image width")->check(CLI::Range(1, 16384))->capture_default_str();
  c->add_option("--height", no->height, "Image height")->check(CLI::Range(1, 16384))->capture_default_str();
  c->add_option("--node-memory", no->node_memory, "Memory per node")->capture_default_str();
  c->add_option("--network", no->network, "none, ipsc2 or cluster")
      ->check(CLI::IsMember({"none", "ipsc2", "cluster"}))
      ->capture_default_str();
  c->add_option("--schedule-window", no->schedule_window_us, "Virtual-time scheduling window, microseconds")
      ->capture_default_str();
  c->add_option("--json", no->json_path, "Also write the table as JSON to this file");
  c->add_option("--mode", no->mode, "Node mode: replicated or svm")
      ->check(CLI::IsMember({"replicated", "svm"}))
      ->capture_default_str();
  c->add_option("--page-size", no->page_size, "svm: page size, bytes")->capture_default_str();
  c->add_option("--cache", no->cache_pages, "svm: cache pages per node (0 = all free memory)")->capture_default_str();
  c->add_option("--repeat", no->repeat, "Runs per row; the best (lowest T_p) is shown")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  c->callback([no] { run_bench_nodes(*no); });
}

}  // namespace raynode::apps
