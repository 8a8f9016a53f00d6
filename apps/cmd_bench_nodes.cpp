// `raynode bench mailbox` and `raynode bench nodes`: benchmarks of the node
// emulator (nodes/). Timings only; nothing here is a pass/fail check.
//
//  * bench mailbox: raw Mailbox throughput with P producer threads and one
//    blocking consumer (messages/s), and the round-trip latency of a
//    ping-pong between two emulated nodes through NodeContext (futex waits).
//  * bench nodes SCENE: renders SCENE in replicated mode for each node count
//    and prints wall time, virtual parallel time T_p, speedup T_1 / T_p and
//    efficiency (the paper's definitions, T_1 = the one-node run).
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
#include "core/scene_source.h"
#include "nodes/machine.h"
#include "nodes/mailbox.h"
#include "nodes/replicated.h"

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
};

void run_bench_nodes(const NodesBenchOptions& o) {
  const core::Scene scene = core::load_scene(o.source);
  const core::Database db = core::make_database(scene);
  const core::Grid grid = core::build_grid(db);
  fmt::print("replicated {} {}x{}, network {}, node memory {}, {} hardware threads\n", o.source.spec, o.width,
             o.height, o.network, o.node_memory, std::thread::hardware_concurrency());
  fmt::print("{:>6} {:>9} {:>11} {:>9} {:>10} {:>10} {:>8}\n", "nodes", "wall_s", "T_p_s", "speedup", "efficiency",
             "work_s", "grants");
  nlohmann::json rows = nlohmann::json::array();
  double t1 = 0;
  const nodes::NetworkModel network = nodes::make_network(o.network);
  for (int n : o.nodes) {
    nodes::ReplicatedParams p;
    p.render.width = o.width;
    p.render.height = o.height;
    p.machine.nodes = std::uint32_t(n);
    p.machine.node_memory = nodes::parse_bytes(o.node_memory);
    p.machine.network = network;
    p.machine.schedule_window_s = o.schedule_window_us * 1e-6;
    const auto t0 = std::chrono::steady_clock::now();
    const nodes::ReplicatedResult r = nodes::render_replicated(db, grid, p);
    const double wall = seconds_since(t0);
    const double tp = r.run.parallel_time_s;
    if (n == 1) t1 = tp;
    double work = 0;
    std::uint64_t grants = 0;
    for (const auto& nr : r.run.nodes) work += nr.counters.busy_s;
    for (const auto& w : r.work) grants += w.grants_given;
    const double speedup = t1 > 0 ? t1 / tp : 0;
    fmt::print("{:>6} {:>9.3f} {:>11.5f} {:>9.2f} {:>10.3f} {:>10.4f} {:>8}\n", n, wall, tp, speedup,
               speedup / double(n), work, grants);
    rows.push_back({{"nodes", n},
                    {"wall_s", wall},
                    {"parallel_time_s", tp},
                    {"speedup", speedup},
                    {"efficiency", speedup / double(n)},
                    {"work_s", work},
                    {"grants", grants}});
  }
  if (t1 == 0) fmt::print("(no 1-node run in --nodes: speedup needs T_1)\n");
  if (!o.json_path.empty()) {
    std::ofstream f(o.json_path);
    f << nlohmann::json{{"scene", o.source.spec}, {"network", o.network}, {"rows", rows}}.dump(2) << "\n";
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
  CLI::App* c = bench->add_subcommand("nodes", "Node emulator: replicated-mode render for several node counts "
                                               "(wall time, virtual T_p, speedup, efficiency)");
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
  c->callback([no] { run_bench_nodes(*no); });
}

}  // namespace raynode::apps
