// `raynode bench mpi`: MPI's latency and bandwidth on this machine, raw and
// through the MPI transport as the nodes see it, and a machine description
// (--machine) with the transport's figures, so that the emulator can
// predict what the MPI runs measure. Run under `mpirun -np 2` (ranks past 1
// wait); only rank 0 prints and writes.
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
#include "nodes/machine.h"

namespace raynode::apps {

namespace {

struct BenchMpiOptions {
  std::vector<std::size_t> sizes{8, 1024, 16384, 65536};
  int repeats = 2000;
  std::string machine_out;
  std::string json_path;
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
  }
  for (const Row& r : rows)
    table.push_back({{"bytes", r.bytes}, {"mpi_one_way_s", r.mpi_s}, {"transport_one_way_s", r.transport_s}});
  if (!o.json_path.empty())
    files->text(json_out, nlohmann::json{{"ranks", transport->processes()},
                                         {"repeats", o.repeats},
                                         {"rows", table},
                                         {"transport_latency_s", latency},
                                         {"transport_per_byte_s", per_byte}}
                                  .dump(2) +
                              "\n");
  if (!o.machine_out.empty()) {
    const nlohmann::json machine{
        {"name", "mpi-measured"},
        {"about", fmt::format("This host's MPI transport as `raynode bench mpi` measured it ({} ranks, {} round trips "
                              "per size): a message's one-way time through the transport, latency at {} B plus the "
                              "slope to {} B. CPU clock, as the MPI runs measure wall time.",
                              transport->processes(), o.repeats, small.bytes, large.bytes)},
        {"clock", "cpu"},
        {"network",
         {{"latency_s", latency}, {"per_byte_s", per_byte}, {"per_hop_s", 0.0}, {"service_s", 0.0}}}};
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
                "Write a machine description (--machine FILE) with the transport's latency and per-byte time");
  add_json_option(*c, o->json_path, "The table");
  c->callback([o] { run_bench_mpi(*o); });
}

}  // namespace raynode::apps
