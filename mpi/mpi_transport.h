// The MPI transport: the same node programs on MPI ranks, one node per rank,
// the host a thread of rank 0 (docs/architecture.md, "Transports").
//
// Place in the data flow: `raynode render --transport mpi` under `mpirun -np
// N` opens an MpiSession, builds one MpiTransport over MPI_COMM_WORLD and
// puts it in MachineParams::transport; the machine then runs node r on rank
// r and the host on rank 0, and every message between ranks goes through
// MpiTransport::send (a record in its destination rank's batch, each batch
// one non-blocking MPI_Isend; rays and pixel contributions wait for a
// fuller batch, every other message leaves at once) and its receiving
// thread (MPI_Improbe / MPI_Mrecv, then each record to its receiver's
// mailbox). Requires MPI_THREAD_MULTIPLE (Open MPI provides it).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "nodes/transport.h"

namespace raynode::mpi {

/// MPI for this process: MPI_Init_thread(MPI_THREAD_MULTIPLE) on the first
/// call, MPI_Finalize at end_session(). Throws std::runtime_error when MPI
/// cannot start or lacks thread support.
void start_session();
/// Is MPI started (and not ended)?
bool session_started();
/// This process's rank and the world's size (0 and 1 before start_session()).
int world_rank();
int world_size();
/// Ends MPI: MPI_Finalize after a success (`exit_code` 0); after a failure,
/// with other ranks, MPI_Abort(exit_code), since they cannot be told
/// otherwise and would wait for this one for ever. No effect when MPI was
/// never started.
void end_session(int exit_code);

/// Wall seconds of MPI_Send/MPI_Recv ping-pong between ranks 0 and 1: half
/// the mean round trip of `repeats` messages of `bytes` bytes. Collective
/// over MPI_COMM_WORLD (ranks beyond 1 wait); rank 0 gets the figure, the
/// others 0.
double ping_pong_s(std::size_t bytes, int repeats);

/// `rounds` times: phases[0] on each rank in turn while the others sleep
/// (polling a barrier every 0.2 ms, so that they take no core and share no
/// core's caches), then each later phase on every rank at once (it may be
/// collective). A phase returns the figure it measured. Collective over
/// MPI_COMM_WORLD. Returns on rank 0, per phase, the figures at index
/// round * world_size() + rank; elsewhere, empty vectors.
std::vector<std::vector<double>> phase_figures(const std::vector<std::function<double()>>& phases, int rounds);

/// A nodes::Transport over a duplicate of MPI_COMM_WORLD: process = rank,
/// node r on rank r, the host on rank 0. start_session() must have been
/// called.
class MpiTransport final : public nodes::Transport {
 public:
  MpiTransport();
  ~MpiTransport() override;
  MpiTransport(const MpiTransport&) = delete;
  MpiTransport& operator=(const MpiTransport&) = delete;

  std::string name() const override { return "mpi"; }
  std::uint32_t processes() const override;
  std::uint32_t process() const override;
  std::uint32_t process_of(nodes::NodeId id, std::uint32_t nodes) const override;
  void start(Deliver deliver) override;
  void send(nodes::NodeId dest, const nodes::MessageHeader& header,
            std::span<const std::span<const std::byte>> parts, std::uint32_t nodes) override;
  void finish() override;
  void stop() noexcept override;
  bool poll() override;
  void note_waiting(int delta) noexcept override;
  void gather(std::span<const std::byte> mine, std::span<std::byte> all) override;
  /// One-sided reads: an MPI window over each rank's region (MPI_Win_create,
  /// MPI_Win_lock_all), read with MPI_Get and MPI_Win_flush (passive target).
  bool reads_remote() const override { return true; }
  void expose(std::span<const std::byte> region) override;
  void read(std::uint32_t process, std::size_t offset, std::span<std::byte> into) override;
  void conceal() override;

 private:
  struct State;
  std::unique_ptr<State> s_;
};

}  // namespace raynode::mpi
