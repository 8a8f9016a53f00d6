// How messages leave this process: the seam between the emulated machine and
// a real distributed engine (docs/architecture.md, "Transports").
//
// Place in the data flow: with MachineParams::transport null (the default),
// every participant runs in this process and a send is a push into the
// receiver's mailbox. With a transport, this process runs only the
// participants the transport says are local (with MPI: node r on rank r,
// the host as one more thread of rank 0); a send to any other participant
// goes to Transport::send, and the transport's own thread hands what
// arrives for a local participant to `deliver`, which pushes it into that
// participant's mailbox. Node programs cannot tell the difference: they
// send and receive through their NodeContext either way.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "nodes/arena.h"
#include "nodes/message.h"

namespace raynode::nodes {

/// A set of processes that together run one machine: each runs some of its
/// participants and carries messages between them.
class Transport {
 public:
  /// Called on the transport's receiving thread for each message that
  /// arrives for a participant of this process: `payload` is valid for the
  /// call only. Must return only once the message is delivered (a full
  /// mailbox is waited for) or the run is stopping.
  using Deliver = std::function<void(NodeId dest, const MessageHeader& header, std::span<const std::byte> payload)>;

  virtual ~Transport() = default;

  /// "mpi", for reports.
  virtual std::string name() const = 0;
  /// Processes taking part (MPI: the communicator's size), >= 1.
  virtual std::uint32_t processes() const = 0;
  /// This process's index, 0 .. processes() - 1; process 0 runs the host.
  virtual std::uint32_t process() const = 0;
  /// The process that runs node `id` (or the host: kHost) on a machine of
  /// `nodes` nodes.
  virtual std::uint32_t process_of(NodeId id, std::uint32_t nodes) const = 0;

  /// Starts receiving: from now until finish(), `deliver` is called for every
  /// message sent to a participant of this process. Collective: returns
  /// when every process receives, so that their runs start together.
  virtual void start(Deliver deliver) = 0;
  /// Sends a message to a participant of another process. Never refuses
  /// (the receiving process queues it until its mailbox has room; the
  /// machine itself refuses a ray beyond the sender's credits,
  /// MachineState::ray_credits); thread safe. Throws std::runtime_error when the engine fails.
  virtual void send(NodeId dest, const MessageHeader& header, std::span<const std::span<const std::byte>> parts,
                    std::uint32_t nodes) = 0;
  /// After this process's participants have all returned: waits until every
  /// message any process sent to this one has been delivered (or dropped,
  /// for a participant that had finished), then stops receiving. Collective:
  /// every process calls it once per run.
  virtual void finish() = 0;
  /// Stops receiving at once, without waiting for the other processes (a
  /// failed run); no effect when not receiving.
  virtual void stop() noexcept = 0;
  /// Receives at most one waiting message on the calling thread (a
  /// participant looking for its mail) and hands it to the Deliver of
  /// start(); returns whether one came. Never waits for another thread's
  /// delivery (it may wait for room in this participant's mailbox). One
  /// sender's messages are delivered in the order sent, whichever thread
  /// takes them. Thread safe; only between start() and finish().
  virtual bool poll() = 0;
  /// A node of this process starts (+1) or ends (-1) blocking for mail:
  /// while one waits, its core is free and the transport should look for
  /// messages at once; while all compute, it should stay off their cores.
  /// Thread safe; a hint.
  virtual void note_waiting(int delta) noexcept = 0;
  // --- One-sided reads (remote memory access), optional -------------------
  /// Does read() work?
  virtual bool reads_remote() const { return false; }
  /// Collective, once per run on every process (from its node's setup):
  /// lets the other processes read `region` (read()) until conceal().
  virtual void expose(std::span<const std::byte> region) {
    throw std::logic_error(name() + " transport: no one-sided reads");
  }
  /// Copies into `into` the bytes at `offset` of `process`'s exposed region,
  /// without that process taking part. Thread safe.
  virtual void read(std::uint32_t process, std::size_t offset, std::span<std::byte> into) {
    throw std::logic_error(name() + " transport: no one-sided reads");
  }
  /// Collective: withdraws this process's region (before its memory goes).
  virtual void conceal() {}

  /// Collective: process 0 gets every process's `mine` (all of the same
  /// size) in process order in `all` (processes() x mine.size() bytes);
  /// other processes leave `all` untouched.
  virtual void gather(std::span<const std::byte> mine, std::span<std::byte> all) = 0;
};

/// Collective, one node per process: process 0 gets each process's own entry
/// of `per_node` (entry i from process i), as plain bytes.
template <class T>
void gather_per_node(Transport& t, std::vector<T>& per_node) {
  static_assert(std::is_trivially_copyable_v<T>, "gathered per node as plain bytes");
  const std::uint32_t me = t.process();
  t.gather(std::as_bytes(std::span<const T>(&per_node.at(me), 1)), std::as_writable_bytes(std::span<T>(per_node)));
}

}  // namespace raynode::nodes
