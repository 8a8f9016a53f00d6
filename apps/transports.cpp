#include "apps/transports.h"

#include "apps/commands.h"

#ifdef RAYNODE_HAVE_MPI
#include "mpi/mpi_transport.h"
#endif

namespace raynode::apps {

bool have_mpi_transport() {
#ifdef RAYNODE_HAVE_MPI
  return true;
#else
  return false;
#endif
}

std::unique_ptr<nodes::Transport> make_transport(const std::string& name) {
  if (name == "local") return nullptr;
  if (name != "mpi") throw UsageError("--transport must be local or mpi, got '" + name + "'");
#ifdef RAYNODE_HAVE_MPI
  mpi::start_session();
  return std::make_unique<mpi::MpiTransport>();
#else
  throw UsageError("--transport mpi: this raynode was built without MPI (install libopenmpi-dev and openmpi-bin, "
                   "then configure again)");
#endif
}

int transport_rank() {
#ifdef RAYNODE_HAVE_MPI
  return mpi::world_rank();
#else
  return 0;
#endif
}

int transport_ranks() {
#ifdef RAYNODE_HAVE_MPI
  return mpi::world_size();
#else
  return 1;
#endif
}

double mpi_ping_pong_s(std::size_t bytes, int repeats) {
#ifdef RAYNODE_HAVE_MPI
  return mpi::ping_pong_s(bytes, repeats);
#else
  (void)bytes, (void)repeats;
  throw UsageError("this raynode was built without MPI");
#endif
}

std::vector<std::vector<double>> mpi_phase_figures(const std::vector<std::function<double()>>& phases, int rounds) {
#ifdef RAYNODE_HAVE_MPI
  return mpi::phase_figures(phases, rounds);
#else
  (void)phases, (void)rounds;
  throw UsageError("this raynode was built without MPI");
#endif
}

void end_transport_session(int exit_code) {
#ifdef RAYNODE_HAVE_MPI
  mpi::end_session(exit_code);
#else
  (void)exit_code;
#endif
}

}  // namespace raynode::apps
