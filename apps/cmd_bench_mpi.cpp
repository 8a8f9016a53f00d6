// `raynode bench mpi`: MPI's latency and bandwidth on this machine, raw and
// through the MPI transport as the nodes see it; what a node's work costs
// on ranks that share this machine (a probe: the co-running slowdown and
// the time of a look for mail); the model clock's unit costs fitted here;
// and a machine description (--machine) with these figures, so that the
// emulator can predict what the MPI runs measure. Run under `mpirun -np N`
// as the runs it predicts, one rank per core (the latency is measured
// between ranks 0 and 1; the others wait); only rank 0 prints and writes.
#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <optional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "apps/commands.h"
#include "apps/node_runs.h"
#include "apps/output_files.h"
#include "apps/transports.h"
#include "core/database.h"
#include "core/grid.h"
#include "core/scene_source.h"
#include "nodes/machine.h"
#include "nodes/network.h"

namespace raynode::apps {

namespace {

struct BenchMpiOptions {
  std::vector<std::size_t> sizes{8, 1024, 16384, 65536};
  int repeats = 2000;
  std::string machine_out;
  std::string json_path;
  std::string probe = "teapot:8";  ///< the probe's scene
  int probe_tessellate = 0;
  int probe_size = 256;            ///< pixels on a side
  int probe_rounds = 5;            ///< 0: no probe, corun_slowdown 1 and poll_s 0
};

/// A message's one-way time through `transport` (half a round trip between
/// nodes 0 and 1: send, the receiving rank's delivery into the mailbox, the
/// node's receive), wall seconds; valid on rank 0.
double transport_one_way_s(nodes::Transport& transport, std::size_t bytes, int repeats) {
  nodes::MachineParams mp;
  mp.nodes = transport.processes();
  mp.transport = &transport;
  mp.mailbox_capacity = 4;
  mp.node_memory = 8 * std::max<std::size_t>(bytes, 256) + (std::size_t(1) << 20);
  mp.timeout_s = 120;
  return node_round_trip_s(mp, bytes, std::uint64_t(repeats)) / 2;
}

/// The probe's figures (rank 0): medians over its rounds.
struct Probe {
  double alone_s = 0;      ///< one node's busy seconds, alone on the machine
  double shared_s = 0;     ///< the same with every rank running one at once
  double transport_s = 0;  ///< the nodes' busy seconds summed, one node per rank on the transport
  double mail_checks = 0;  ///< the nodes' looks for mail in that run
  double corun_slowdown = 1;  ///< shared / alone
  double poll_s = 0;          ///< (transport - corun_slowdown x alone) / mail_checks, >= 0
  std::vector<double> round_slowdowns, round_poll_s;
};

/// The probe: replicated mode's node program on the probe scene (its view
/// at probe_size pixels, adaptive grid, CPU clock, free network), each
/// round in three phases: one emulated node on each rank in turn while the
/// others sleep (alone); one on every rank at once (shared: the ranks share
/// this machine's caches and memory bandwidth); one node per rank on
/// `transport` (the same pixels and rays as one node alone, now with the
/// transport's looks for mail). Busy seconds are the nodes' CPU time. So a
/// node's work on ranks costs corun_slowdown x its work alone, plus poll_s
/// per look for mail: the emulator's corun_slowdown and network poll_s.
Probe measure_probe(const BenchMpiOptions& o, nodes::Transport& transport) {
  Probe p;
  if (o.probe_rounds == 0) return p;
  const core::Database db = core::make_database(core::load_scene(tracing_source(o.probe, o.probe_tessellate)));
  core::GridParams gp;
  gp.kind = core::GridKind::kAdaptive;
  const core::Grid grid = core::build_grid(db, gp);
  NodeRunOptions no;
  no.width = no.height = o.probe_size;
  no.clock = "cpu";
  no.network = "none";
  no.node_memory = "256MiB";
  const NodeRunSpec local = make_node_run_spec(no);
  NodeRunSpec ranked = local;
  ranked.machine.transport = &transport;
  const std::uint32_t ranks = transport.processes();
  std::vector<double> checks;  // rank 0: the transport phase's looks for mail, per round
  auto one_node = [&] { return run_node_mode(db, grid, "replicated", local, 1).work_s; };
  auto on_ranks = [&] {
    const NodeRun r = run_node_mode(db, grid, "replicated", ranked, ranks);
    checks.push_back(double(r.mail_checks));
    return r.work_s;
  };
  (void)one_node();  // warms the caches and pages in the database
  const std::vector<std::vector<double>> f = mpi_phase_figures({one_node, one_node, on_ranks}, o.probe_rounds);
  if (f[0].empty()) return p;  // not rank 0
  std::vector<double> alone, shared, ranked_s;
  for (int round = 0; round < o.probe_rounds; ++round) {
    double a = 0, s = 0;
    for (std::uint32_t r = 0; r < ranks; ++r) {
      a += f[0][std::size_t(round) * ranks + r] / ranks;
      s += f[1][std::size_t(round) * ranks + r] / ranks;
    }
    const double t = f[2][std::size_t(round) * ranks];  // rank 0 holds the run's summed busy time
    const double slowdown = a > 0 ? s / a : 1.0;
    alone.push_back(a), shared.push_back(s), ranked_s.push_back(t);
    p.round_slowdowns.push_back(slowdown);
    p.round_poll_s.push_back(checks[std::size_t(round)] > 0
                                 ? std::max(0.0, t - std::max(1.0, slowdown) * a) / checks[std::size_t(round)]
                                 : 0.0);
  }
  p.alone_s = median(alone);
  p.shared_s = median(shared);
  p.transport_s = median(ranked_s);
  p.mail_checks = median(checks);
  p.corun_slowdown = median(p.round_slowdowns);
  p.poll_s = median(p.round_poll_s);
  return p;
}

/// The unit costs by name, seconds (a machine description's "cost_model").
nlohmann::json cost_model_json(const core::CostModel& m) {
  nlohmann::json j = nlohmann::json::object();
  for (int k = 0; k < core::kCostFeatureCount; ++k)
    j[core::cost_feature_name(core::CostFeature(k))] = m.unit_s[std::size_t(k)];
  return j;
}

void run_bench_mpi(const BenchMpiOptions& o) {
  const std::unique_ptr<nodes::Transport> transport = make_transport("mpi");
  if (transport->processes() < 2)
    throw UsageError(fmt::format("bench mpi measures between two ranks: run it under mpirun -np 2 (this job has {})",
                                 transport->processes()));
  const bool writer = transport->process() == 0;
  std::optional<OutputFiles> files;
  std::size_t machine_out = 0, json_out = 0;
  if (writer) {
    files.emplace();
    if (!o.machine_out.empty()) machine_out = files->add(o.machine_out, "--machine-out file", true);
    if (!o.json_path.empty()) json_out = files->add(o.json_path, "--json file", true);
  }
  struct Row {
    std::size_t bytes;
    double mpi_s, transport_s;
  };
  std::vector<Row> rows;
  for (std::size_t bytes : o.sizes) {
    const double raw = mpi_ping_pong_s(bytes, o.repeats);
    const double via = transport_one_way_s(*transport, bytes, o.repeats);
    rows.push_back({bytes, raw, via});
  }
  const Probe probe = measure_probe(o, *transport);
  // The model clock's unit costs on this host and its tracing speed (the
  // figures' scale: they are this host's seconds, and the model clock's are
  // the cost model's), measured on rank 0 while the others sleep.
  core::CostModel cost_model;
  double seconds_per_ray = 0;
  (void)mpi_phase_figures({[&] {
                            if (writer) {
                              cost_model = fit_cost_model_on_host();
                              seconds_per_ray = nodes::calibrate_seconds_per_ray();
                            }
                            return 0.0;
                          }},
                          1);
  // The emulator takes a slowdown of at least 1: a measured one below is the host's noise.
  const double slowdown = std::max(1.0, probe.corun_slowdown);
  if (!writer) return;
  // Latency: the smallest message's one-way time; per byte: the slope to the largest.
  const Row& small = rows.front();
  const Row& large = rows.back();
  auto slope = [&](double Row::*t) {
    return large.bytes > small.bytes ? std::max(0.0, (large.*t - small.*t) / double(large.bytes - small.bytes)) : 0.0;
  };
  const double latency = small.transport_s, per_byte = slope(&Row::transport_s);
  nlohmann::json table = nlohmann::json::array();
  if (o.json_path != "-") {
    fmt::print("{:>9}  {:>14}  {:>14}  {:>16}\n", "bytes", "MPI one-way", "transport", "transport MB/s");
    for (const Row& r : rows)
      fmt::print("{:>9}  {:>11.2f} us  {:>11.2f} us  {:>16.1f}\n", r.bytes, r.mpi_s * 1e6, r.transport_s * 1e6,
                 double(r.bytes) / r.transport_s / 1e6);
    fmt::print("transport: latency {:.2f} us, {:.3g} s per byte ({:.0f} MB/s); raw MPI: latency {:.2f} us, {:.0f} MB/s\n",
               latency * 1e6, per_byte, per_byte > 0 ? 1e-6 / per_byte : 0.0, small.mpi_s * 1e6,
               slope(&Row::mpi_s) > 0 ? 1e-6 / slope(&Row::mpi_s) : 0.0);
    if (o.probe_rounds > 0)
      fmt::print("probe: {} at {}x{}, replicated, median of {} rounds: one node {:.4f} s alone, {:.4f} s beside "
                 "{} others (co-running slowdown {:.3f}); {} nodes on ranks {:.4f} s over {:.0f} looks for mail "
                 "({:.3f} us a look)\n",
                 o.probe, o.probe_size, o.probe_size, o.probe_rounds, probe.alone_s, probe.shared_s,
                 transport->processes() - 1, probe.corun_slowdown, transport->processes(), probe.transport_s,
                 probe.mail_checks, probe.poll_s * 1e6);
  }
  for (const Row& r : rows)
    table.push_back({{"bytes", r.bytes}, {"mpi_one_way_s", r.mpi_s}, {"transport_one_way_s", r.transport_s}});
  if (!o.json_path.empty())
    files->text(json_out, nlohmann::json{{"ranks", transport->processes()},
                                         {"repeats", o.repeats},
                                         {"rows", table},
                                         {"transport_latency_s", latency},
                                         {"transport_per_byte_s", per_byte},
                                         {"probe",
                                          {{"scene", o.probe},
                                           {"tessellate", o.probe_tessellate},
                                           {"size", o.probe_size},
                                           {"rounds", o.probe_rounds},
                                           {"alone_s", probe.alone_s},
                                           {"shared_s", probe.shared_s},
                                           {"transport_s", probe.transport_s},
                                           {"mail_checks", probe.mail_checks},
                                           {"round_slowdowns", probe.round_slowdowns},
                                           {"round_poll_s", probe.round_poll_s},
                                           {"corun_slowdown", probe.corun_slowdown},
                                           {"poll_s", probe.poll_s}}}}
                                  .dump(2) +
                              "\n");
  if (!o.machine_out.empty()) {
    const nlohmann::json machine{
        {"name", "mpi-measured"},
        {"about", fmt::format("This host's MPI transport as `raynode bench mpi` measured it ({} ranks, {} round trips "
                              "per size): a message's one-way time through the transport, latency at {} B plus the "
                              "slope to {} B; a node's co-running slowdown and its time per look for mail, from {} at "
                              "{}x{} on {} ranks (median of {} rounds); the model clock's unit costs as `raynode bench "
                              "cost-model` fits them here; seconds of this host, whose tracing speed seconds_per_ray "
                              "gives. CPU clock, as the MPI runs measure wall time.",
                              transport->processes(), o.repeats, small.bytes, large.bytes, o.probe, o.probe_size,
                              o.probe_size, transport->processes(), o.probe_rounds)},
        {"clock", "cpu"},
        {"corun_slowdown", slowdown},
        {"cost_model", cost_model_json(cost_model)},
        {"network",
         {{"latency_s", latency},
          {"per_byte_s", per_byte},
          {"per_hop_s", 0.0},
          {"service_s", 0.0},
          {"poll_s", probe.poll_s},
          {"seconds_per_ray", seconds_per_ray}}}};
    files->text(machine_out, machine.dump(2) + "\n");
  }
  files->commit();
}

}  // namespace

void register_bench_mpi_command(CLI::App& app) {
  auto o = std::make_shared<BenchMpiOptions>();
  CLI::App* c = app.get_subcommand("bench")->add_subcommand(
      "mpi", "MPI latency and bandwidth between two ranks, raw and through the MPI transport (run under mpirun -np 2)");
  c->footer("Example: mpirun -np 2 raynode bench mpi --machine-out mpi.json; then raynode render SCENE --nodes 2 "
            "--machine mpi.json predicts what mpirun -np 2 raynode render SCENE --transport mpi measures.");
  c->add_option("--sizes", o->sizes, "Message sizes in bytes, comma-separated (the first gives the latency)")
      ->delimiter(',')
      ->check(CLI::Range(std::size_t(1), std::size_t(1) << 24))
      ->capture_default_str();
  c->add_option("--repeats", o->repeats, "Round trips per size")->check(CLI::Range(1, 10000000))->capture_default_str();
  c->add_option("--machine-out", o->machine_out,
                "Write a machine description (--machine FILE) with the transport's latency and per-byte time, the "
                "probe's co-running slowdown and time per look for mail, and the model clock's unit costs fitted "
                "on this host");
  c->add_option("--probe", o->probe,
                "The probe's scene (NFF or mesh file, or SPD name[:size]): rendered by one node on each rank alone, "
                "then on all ranks at once, then by one node per rank over MPI; gives the machine description's "
                "corun_slowdown and poll_s")
      ->capture_default_str();
  c->add_option("--probe-tessellate", o->probe_tessellate, "Tessellate the probe's spheres and cones (SPD -t R)")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  c->add_option("--probe-size", o->probe_size, "The probe's image, pixels on a side")
      ->check(CLI::Range(1, 8192))
      ->capture_default_str();
  c->add_option("--probe-rounds", o->probe_rounds,
                "Probe rounds (each: a node on every rank alone in turn, on all ranks at once, then one node per "
                "rank over MPI); 0: no probe, corun_slowdown 1 and poll_s 0")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  add_json_option(*c, o->json_path, "The table");
  c->callback([o] { run_bench_mpi(*o); });
}

}  // namespace raynode::apps
