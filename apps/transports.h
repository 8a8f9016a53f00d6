// `--transport local|mpi`: where a node mode's participants run. local (the
// default) is the emulator, every node a thread of this process; mpi runs
// node r on MPI rank r and the host on rank 0 (mpi/mpi_transport.h).
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "nodes/transport.h"

namespace raynode::apps {

/// Was raynode built with the MPI transport?
bool have_mpi_transport();
/// The transport `name` names: null for "local"; for "mpi" MPI is started
/// (once per process). Throws UsageError for another name or for "mpi" in a
/// build without MPI; std::runtime_error when MPI cannot start.
std::unique_ptr<nodes::Transport> make_transport(const std::string& name);
/// This process's MPI rank and the ranks (0 and 1 without MPI).
int transport_rank();
int transport_ranks();
/// Raw MPI ping-pong between ranks 0 and 1 (mpi::ping_pong_s): half the
/// mean round trip of `repeats` messages of `bytes` bytes, wall seconds, on
/// rank 0 (0 elsewhere). Throws UsageError in a build without MPI.
double mpi_ping_pong_s(std::size_t bytes, int repeats);
/// mpi::phase_figures: phases[0] on each rank in turn, the others on all
/// ranks at once, `rounds` times; on rank 0 per phase the figures at index
/// round * ranks + rank (empty elsewhere). Throws UsageError in a build
/// without MPI.
std::vector<std::vector<double>> mpi_phase_figures(const std::vector<std::function<double()>>& phases, int rounds);
/// At the end of main: ends MPI if it was started (a failure on one rank
/// aborts the others, which would wait for it for ever).
void end_transport_session(int exit_code);

}  // namespace raynode::apps
