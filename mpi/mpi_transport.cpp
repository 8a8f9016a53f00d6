
#include "mpi/mpi_transport.h"

#include <fmt/core.h>
#include <mpi.h>
#include <sys/resource.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <exception>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

namespace raynode::mpi {

namespace {

bool g_started = false;

/// raynode messages travel in MPI messages of this tag, each a batch of
/// one or more records: the record's bytes (a uint32), the destination
/// participant, the header, then the payload.
constexpr int kMessageTag = 7;
constexpr int kPingTag = 8;
/// Rays and pixel contributions (dataflow's stream) wait in their
/// destination rank's batch until it holds this many bytes, another kind of
/// message is sent, a node of this rank waits for mail, or the receiving
/// thread passes by (at least every millisecond): one MPI message per
/// batch instead of one per ray. Any other message leaves at once, after
/// the batches before it.
constexpr std::size_t kBatchBytes = 8 * 1024;

bool batched(nodes::MessageType t) { return t == nodes::MessageType::kRay || t == nodes::MessageType::kContribution; }

void check(int rc, const char* what) {
  if (rc == MPI_SUCCESS) return;
  char text[MPI_MAX_ERROR_STRING];
  int len = 0;
  MPI_Error_string(rc, text, &len);
  throw std::runtime_error(fmt::format("MPI: {} failed: {}", what, std::string(text, std::size_t(len))));
}

}  // namespace

void start_session() {
  if (g_started) return;
  int provided = 0;
  check(MPI_Init_thread(nullptr, nullptr, MPI_THREAD_MULTIPLE, &provided), "MPI_Init_thread");
  g_started = true;
  if (provided < MPI_THREAD_MULTIPLE)
    throw std::runtime_error(fmt::format("MPI: this MPI library gives thread level {}, and the MPI transport needs "
                                         "MPI_THREAD_MULTIPLE ({}): node, host and receiving threads all call MPI",
                                         provided, int(MPI_THREAD_MULTIPLE)));
}

bool session_started() { return g_started; }

int world_rank() {
  int r = 0;
  if (g_started) MPI_Comm_rank(MPI_COMM_WORLD, &r);
  return r;
}

int world_size() {
  int n = 1;
  if (g_started) MPI_Comm_size(MPI_COMM_WORLD, &n);
  return n;
}

void end_session(int exit_code) {
  if (!g_started) return;
  if (exit_code != 0 && world_size() > 1) MPI_Abort(MPI_COMM_WORLD, exit_code);
  g_started = false;
  MPI_Finalize();
}

double ping_pong_s(std::size_t bytes, int repeats) {
  const int rank = world_rank();
  std::vector<std::byte> buf(std::max<std::size_t>(bytes, 1));
  const int count = int(bytes);
  MPI_Barrier(MPI_COMM_WORLD);
  const double t0 = MPI_Wtime();
  if (rank <= 1 && world_size() > 1) {
    const int peer = 1 - rank;
    for (int i = 0; i < repeats; ++i) {
      if (rank == 0) {
        MPI_Send(buf.data(), count, MPI_BYTE, peer, kPingTag, MPI_COMM_WORLD);
        MPI_Recv(buf.data(), count, MPI_BYTE, peer, kPingTag, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
      } else {
        MPI_Recv(buf.data(), count, MPI_BYTE, peer, kPingTag, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        MPI_Send(buf.data(), count, MPI_BYTE, peer, kPingTag, MPI_COMM_WORLD);
      }
    }
  }
  const double t = MPI_Wtime() - t0;
  MPI_Barrier(MPI_COMM_WORLD);
  return rank == 0 && repeats > 0 ? t / (2.0 * repeats) : 0.0;
}

namespace {

/// A barrier that waits asleep: MPI_Ibarrier tested every 0.2 ms.
void sleeping_barrier() {
  MPI_Request request = MPI_REQUEST_NULL;
  check(MPI_Ibarrier(MPI_COMM_WORLD, &request), "MPI_Ibarrier");
  for (int done = 0;;) {
    check(MPI_Test(&request, &done, MPI_STATUS_IGNORE), "MPI_Test");
    if (done) return;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
}

}  // namespace

std::vector<std::vector<double>> phase_figures(const std::vector<std::function<double()>>& phases, int rounds) {
  const int rank = world_rank(), size = world_size();
  const std::size_t k = phases.size();
  std::vector<double> mine;  // per round, per phase
  for (int round = 0; round < rounds; ++round)
    for (std::size_t phase = 0; phase < k; ++phase) {
      double figure = 0;
      if (phase == 0) {
        for (int turn = 0; turn < size; ++turn) {
          sleeping_barrier();
          if (turn == rank) figure = phases[0]();
        }
      } else {
        sleeping_barrier();
        figure = phases[phase]();
      }
      mine.push_back(figure);
    }
  sleeping_barrier();
  std::vector<double> all(rank == 0 ? mine.size() * std::size_t(size) : 0);
  check(MPI_Gather(mine.data(), int(mine.size()), MPI_DOUBLE, all.data(), int(mine.size()), MPI_DOUBLE, 0,
                   MPI_COMM_WORLD),
        "MPI_Gather");
  std::vector<std::vector<double>> out(k);
  if (rank != 0) return out;
  for (std::size_t phase = 0; phase < k; ++phase) {
    out[phase].resize(std::size_t(rounds) * std::size_t(size));
    for (int r = 0; r < size; ++r)
      for (int round = 0; round < rounds; ++round)
        out[phase][std::size_t(round) * std::size_t(size) + std::size_t(r)] =
            all[std::size_t(r) * mine.size() + std::size_t(round) * k + phase];
  }
  return out;
}

struct MpiTransport::State {
  MPI_Comm comm = MPI_COMM_NULL;
  int rank = 0, size = 1;
  Deliver deliver;
  std::thread receiver;
  std::atomic<bool> receiving{false}, stopping{false};
  std::atomic<std::uint64_t> received{0};
  std::atomic<int> waiting{0};  ///< nodes of this rank blocked for mail (note_waiting)
  std::mutex nap_mutex;         ///< the receiving thread's nap, ended early by a node that waits
  std::condition_variable nap;
  MPI_Win window = MPI_WIN_NULL;  ///< expose(): this rank's region, for the others' MPI_Get
  /// MPI messages (batches) this process sent to each rank during the run.
  std::vector<std::uint64_t> sent;
  /// Sends in flight: their requests and buffers (index-aligned).
  std::mutex send_mutex;
  std::vector<MPI_Request> requests;
  std::vector<std::vector<std::byte>> buffers;
  /// Per destination rank, the records waiting to leave as one message
  /// (send_mutex held); `pending`: some batch is not empty.
  std::vector<std::vector<std::byte>> batch;
  std::atomic<bool> pending{false};

  /// Sends rank `to`'s batch, if any, as one MPI message (send_mutex held).
  /// Throws as check() does; the batch then stays, for the next flush.
  void flush(int to) {
    std::vector<std::byte>& b = batch[std::size_t(to)];
    if (b.empty()) return;
    MPI_Request req;
    check(MPI_Isend(b.data(), int(b.size()), MPI_BYTE, to, kMessageTag, comm, &req), "MPI_Isend");
    requests.push_back(req);
    buffers.push_back(std::move(b));
    b = {};
    ++sent[std::size_t(to)];
    if (requests.size() >= 32) reap();
  }
  /// Sends every batch (send_mutex held).
  void flush_all() {
    for (int r = 0; r < size; ++r) flush(r);
    pending.store(false, std::memory_order_relaxed);
  }
  void flush_all_locked() {
    if (!pending.load(std::memory_order_relaxed)) return;
    std::lock_guard<std::mutex> lock(send_mutex);
    flush_all();
  }

  /// Drops the completed sends (send_mutex held).
  void reap() {
    int done = 0;
    std::vector<int> indices(requests.size());
    check(MPI_Testsome(int(requests.size()), requests.data(), &done, indices.data(), MPI_STATUSES_IGNORE),
          "MPI_Testsome");
    if (done == MPI_UNDEFINED || done == 0) return;
    std::size_t w = 0;
    for (std::size_t i = 0; i < requests.size(); ++i) {
      if (requests[i] == MPI_REQUEST_NULL) continue;
      if (w != i) {  // a vector moved onto itself would free the buffer MPI still sends from
        requests[w] = requests[i];
        buffers[w] = std::move(buffers[i]);
      }
      ++w;
    }
    requests.resize(w);
    buffers.resize(w);
  }

  /// Held from a message's probe to its delivery: one sender's messages
  /// then reach the mailboxes in the order MPI matched them, which is the
  /// order they were sent (as the emulator's mailboxes keep it).
  std::mutex receive_mutex;

  /// Takes one waiting message, if any, and delivers it on this thread.
  /// `wait`: block for the receive lock; else give up when another thread
  /// holds it (a participant's poll: the holder may be waiting for room in
  /// the participant's own mailbox).
  bool receive_one(std::vector<std::byte>& buf, bool wait) {
    std::unique_lock<std::mutex> lock(receive_mutex, std::defer_lock);
    if (wait) lock.lock();
    else if (!lock.try_lock()) return false;
    int flag = 0;
    MPI_Message msg;
    MPI_Status status;
    MPI_Improbe(MPI_ANY_SOURCE, kMessageTag, comm, &flag, &msg, &status);
    if (!flag) return false;
    int count = 0;
    MPI_Get_count(&status, MPI_BYTE, &count);
    buf.resize(std::size_t(count));
    MPI_Mrecv(buf.data(), count, MPI_BYTE, &msg, MPI_STATUS_IGNORE);
    // The batch's records, in the order they were sent.
    nodes::NodeId dest = 0;
    nodes::MessageHeader header;
    std::uint32_t record = 0;
    const std::size_t head = sizeof(record) + sizeof(dest) + sizeof(header);
    for (std::size_t at = 0; at + head <= buf.size(); at += record) {
      std::memcpy(&record, buf.data() + at, sizeof(record));
      if (record < head || record > buf.size() - at) break;  // cannot happen: written by send()
      std::memcpy(&dest, buf.data() + at + sizeof(record), sizeof(dest));
      std::memcpy(&header, buf.data() + at + sizeof(record) + sizeof(dest), sizeof(header));
      deliver(dest, header, std::span<const std::byte>(buf.data() + at + head, record - head));
    }
    received.fetch_add(1, std::memory_order_release);
    return true;
  }

  void receive_loop() {
    // The lowest priority: when this rank's node computes, it polls for its
    // own mail (NodeContext::has_mail), and this thread must not take its
    // core; when the node waits, the core is free and this thread runs.
    // (Measured on 2 cores, svm Teapot 512x512 on 2 ranks: 0.202 s at nice
    // 0, 0.172 s at 19.)
    ::setpriority(PRIO_PROCESS, 0, 19);
    std::vector<std::byte> buf;
    int idle = 0;
    while (!stopping.load(std::memory_order_acquire)) {
      try {
        flush_all_locked();  // rays that waited for a fuller batch leave now
      } catch (...) {
        // The batch stays: the next send or finish() on a participant's
        // thread sends it again and reports the failure there.
      }
      if (!receive_one(buf, true)) {
        // A node waits (a page, a work grant, rays): its core is free, so
        // look again at once. Else nap, up to 1 ms: a thread that wakes on
        // a computing node's core costs it its caches (and its clock the
        // refills), and the node takes its own mail meanwhile.
        if (waiting.load(std::memory_order_relaxed) > 0) {
          idle = 0;
          std::this_thread::yield();
        } else {
          ++idle;
          // A node that starts to wait ends the nap (note_waiting).
          std::unique_lock<std::mutex> lock(nap_mutex);
          nap.wait_for(lock, std::chrono::microseconds(std::min(1000, 20 * idle)),
                       [&] { return waiting.load(std::memory_order_relaxed) > 0 || stopping.load(); });
        }
        continue;
      }
      idle = 0;
    }
  }
};

MpiTransport::MpiTransport() : s_(std::make_unique<State>()) {
  if (!g_started) throw std::logic_error("MpiTransport needs mpi::start_session() first");
  check(MPI_Comm_dup(MPI_COMM_WORLD, &s_->comm), "MPI_Comm_dup");
  // Errors come back as codes (check() throws them with their text), not as an abort without a word.
  MPI_Comm_set_errhandler(s_->comm, MPI_ERRORS_RETURN);
  MPI_Comm_rank(s_->comm, &s_->rank);
  MPI_Comm_size(s_->comm, &s_->size);
  s_->sent.assign(std::size_t(s_->size), 0);
  s_->batch.resize(std::size_t(s_->size));
}

MpiTransport::~MpiTransport() {
  stop();
  // MPI_Comm_free is collective: not on the way out of a failure, which
  // ends the job with MPI_Abort (end_session) instead.
  if (g_started && s_->comm != MPI_COMM_NULL && std::uncaught_exceptions() == 0) MPI_Comm_free(&s_->comm);
}

std::uint32_t MpiTransport::processes() const { return std::uint32_t(s_->size); }
std::uint32_t MpiTransport::process() const { return std::uint32_t(s_->rank); }

std::uint32_t MpiTransport::process_of(nodes::NodeId id, std::uint32_t nodes) const {
  return id == nodes::kHost ? 0 : id;
}

void MpiTransport::start(Deliver deliver) {
  stop();
  s_->deliver = std::move(deliver);
  s_->received.store(0);
  std::fill(s_->sent.begin(), s_->sent.end(), 0);
  s_->stopping.store(false);
  s_->receiver = std::thread([st = s_.get()] { st->receive_loop(); });
  s_->receiving.store(true);
  // Every rank receives before any starts its participants, and they start
  // together: each rank's wall time then measures the same run.
  check(MPI_Barrier(s_->comm), "MPI_Barrier");
}

void MpiTransport::send(nodes::NodeId dest, const nodes::MessageHeader& header,
                        std::span<const std::span<const std::byte>> parts, std::uint32_t nodes) {
  const std::uint32_t to = process_of(dest, nodes);
  std::size_t bytes = sizeof(std::uint32_t) + sizeof(dest) + sizeof(header);
  for (const auto& p : parts) bytes += p.size();
  const std::uint32_t record = std::uint32_t(bytes);
  std::lock_guard<std::mutex> lock(s_->send_mutex);
  std::vector<std::byte>& b = s_->batch[to];
  const std::size_t start = b.size();
  b.resize(start + bytes);
  std::byte* at = b.data() + start;
  std::memcpy(at, &record, sizeof(record));
  at += sizeof(record);
  std::memcpy(at, &dest, sizeof(dest));
  at += sizeof(dest);
  std::memcpy(at, &header, sizeof(header));
  at += sizeof(header);
  for (const auto& p : parts) {
    if (!p.empty()) std::memcpy(at, p.data(), p.size());
    at += p.size();
  }
  if (!batched(header.type)) s_->flush_all();  // the batches before it, then this message
  else if (b.size() >= kBatchBytes) s_->flush(int(to));
  else s_->pending.store(true, std::memory_order_relaxed);
}

void MpiTransport::finish() {
  {
    std::lock_guard<std::mutex> lock(s_->send_mutex);
    s_->flush_all();
    check(MPI_Waitall(int(s_->requests.size()), s_->requests.data(), MPI_STATUSES_IGNORE), "MPI_Waitall");
    s_->requests.clear();
    s_->buffers.clear();
  }
  std::vector<std::uint64_t> expected(s_->sent.size());
  check(MPI_Alltoall(s_->sent.data(), 1, MPI_UINT64_T, expected.data(), 1, MPI_UINT64_T, s_->comm), "MPI_Alltoall");
  std::uint64_t total = 0;
  for (std::uint64_t e : expected) total += e;
  while (s_->received.load(std::memory_order_acquire) < total) std::this_thread::sleep_for(std::chrono::microseconds(50));
  stop();
}

void MpiTransport::stop() noexcept {
  if (!s_->receiving.exchange(false)) return;
  {
    std::lock_guard<std::mutex> lock(s_->nap_mutex);
    s_->stopping.store(true, std::memory_order_release);
  }
  s_->nap.notify_one();
  if (s_->receiver.joinable()) s_->receiver.join();
}

bool MpiTransport::poll() {
  thread_local std::vector<std::byte> buf;
  return s_->receiving.load(std::memory_order_relaxed) && s_->receive_one(buf, false);
}

void MpiTransport::note_waiting(int delta) noexcept {
  if (delta > 0) {
    // A node that waits for mail may wait for an answer to what this
    // rank's batches hold: they leave now.
    try {
      s_->flush_all_locked();
    } catch (...) {
      // The batch stays: the next send or finish() reports the failure.
    }
  }
  if (s_->waiting.fetch_add(delta, std::memory_order_relaxed) == 0 && delta > 0) {
    std::lock_guard<std::mutex> lock(s_->nap_mutex);  // the napping thread checks `waiting` under it
    s_->nap.notify_one();
  }
}

void MpiTransport::expose(std::span<const std::byte> region) {
  if (s_->window != MPI_WIN_NULL) throw std::logic_error("MpiTransport::expose: a region is already exposed");
  // MPI takes a non-const base; the others only read it.
  void* base = const_cast<std::byte*>(region.data());
  check(MPI_Win_create(base, MPI_Aint(region.size()), 1, MPI_INFO_NULL, s_->comm, &s_->window),
        "MPI_Win_create (one-sided reads; this MPI may have no one-sided support between these ranks)");
  MPI_Win_set_errhandler(s_->window, MPI_ERRORS_RETURN);
  check(MPI_Win_lock_all(MPI_MODE_NOCHECK, s_->window), "MPI_Win_lock_all");
}

void MpiTransport::read(std::uint32_t process, std::size_t offset, std::span<std::byte> into) {
  check(MPI_Get(into.data(), int(into.size()), MPI_BYTE, int(process), MPI_Aint(offset), int(into.size()), MPI_BYTE,
                s_->window),
        "MPI_Get");
  check(MPI_Win_flush(int(process), s_->window), "MPI_Win_flush");
}

void MpiTransport::conceal() {
  if (s_->window == MPI_WIN_NULL) return;
  MPI_Win_unlock_all(s_->window);
  MPI_Win_free(&s_->window);  // collective: waits until no rank reads any more
}

void MpiTransport::gather(std::span<const std::byte> mine, std::span<std::byte> all) {
  check(MPI_Gather(mine.data(), int(mine.size()), MPI_BYTE, s_->rank == 0 ? all.data() : nullptr,
                   int(mine.size()), MPI_BYTE, 0, s_->comm),
        "MPI_Gather");
}

}  // namespace raynode::mpi
