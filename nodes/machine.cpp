#include "nodes/machine.h"

#include <fmt/core.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <nlohmann/json.hpp>
#include <thread>

#include <sys/resource.h>
#include <unistd.h>

#include "core/stop.h"
#include "nodes/cpu_time.h"

namespace raynode::nodes {

const char* message_type_name(MessageType type) {
  switch (type) {
    case MessageType::kWorkRequest: return "work_request";
    case MessageType::kWorkGrant: return "work_grant";
    case MessageType::kPixels: return "pixels";
    case MessageType::kNodeDone: return "node_done";
    case MessageType::kShutdown: return "shutdown";
    case MessageType::kPageRequest: return "page_request";
    case MessageType::kPageReply: return "page_reply";
    case MessageType::kRay: return "ray";
    case MessageType::kContribution: return "contribution";
    case MessageType::kToken: return "token";
    case MessageType::kControl: return "control";
    case MessageType::kTest: return "test";
    case MessageType::kCount: break;
  }
  return "unknown";
}

MachineState::MachineState(const MachineParams& p)
    : params(p),
      topology(p.topology, p.nodes),
      finished(new std::atomic<bool>[p.nodes]) {
  for (std::uint32_t i = 0; i < p.nodes; ++i) finished[i].store(false, std::memory_order_relaxed);
  nodes.resize(p.nodes);  // null until built: where a transport runs a node elsewhere, for good
  const std::uint32_t permits =
      p.run_permits > 0 ? p.run_permits : std::max(1u, std::thread::hardware_concurrency());
  scheduler = std::make_unique<Scheduler>(
      p.nodes, permits, p.schedule_window_s, [this](std::uint32_t node) { nodes[node]->mailbox().wake(); },
      p.scheduled_mail.value_or(false));
  if (p.network.contention && p.nodes > 1) links = std::make_unique<LinkNetwork>(topology);
  if (p.transport) {
    ray_window = std::int32_t(std::max<std::uint32_t>(1, p.mailbox_capacity / p.nodes));
    const std::size_t pairs = std::size_t(p.nodes + 1) * p.nodes;
    ray_credits.reset(new std::atomic<std::int32_t>[pairs]);
    for (std::size_t i = 0; i < pairs; ++i) ray_credits[i].store(ray_window, std::memory_order_relaxed);
    credits_received.reset(new std::atomic<std::uint64_t>[p.nodes + 1]);
    for (std::uint32_t i = 0; i <= p.nodes; ++i) credits_received[i].store(0, std::memory_order_relaxed);
  }
}

MachineState::~MachineState() = default;

void MachineState::fail(NodeId node, std::exception_ptr error) {
  {
    std::lock_guard<std::mutex> lock(error_mutex_);
    if (!error_) {
      error_ = error;
      error_node_ = node;
    }
  }
  stop_all();
}

void MachineState::stop_all() {
  stop.store(true, std::memory_order_seq_cst);
  for (auto& n : nodes)
    if (n) n->mailbox().wake();
  if (host) host->mailbox().wake();
}

std::exception_ptr MachineState::error() const {
  std::lock_guard<std::mutex> lock(error_mutex_);
  return error_;
}

NodeId MachineState::error_node() const {
  std::lock_guard<std::mutex> lock(error_mutex_);
  return error_node_;
}

Machine::Machine(const MachineParams& params) : params_(params) {
  if (params_.nodes < 1 || params_.nodes > kMaxNodes)
    throw std::invalid_argument(fmt::format("--nodes must be 1..{}, got {}", kMaxNodes, params_.nodes));
  if (params_.node_memory == 0) throw std::invalid_argument("--node-memory must be > 0");
  if (!(params_.corun_slowdown >= 1 && params_.corun_slowdown <= kMaxCorunSlowdown))
    throw std::invalid_argument(
        fmt::format("the co-running slowdown must be 1..{}, got {}", kMaxCorunSlowdown, params_.corun_slowdown));
  if (params_.max_payload == 0) throw std::invalid_argument("message payload limit must be > 0");
  if (params_.mailbox_capacity == 0) params_.mailbox_capacity = 2 * params_.nodes + 32;
  params_.work_grant = resolved_work_grant(params_);
  if (Transport* t = params_.transport) {
    if (params_.nodes != t->processes())
      throw std::invalid_argument(fmt::format("the {} transport runs one node per process: {} processes, {} nodes",
                                              t->name(), t->processes(), params_.nodes));
    check_nodes_fit_host(1, params_.node_memory, host_physical_memory());
    // Each process has its own cores and the links are real: no virtual-time
    // scheduling across processes, no emulated contention.
    params_.schedule_window_s = -1;
    params_.scheduled_mail = false;
    params_.network.contention = false;
  } else {
    check_nodes_fit_host(params_.nodes, params_.node_memory, host_physical_memory());
  }
}

namespace {

/// The message of an exception, prefixed with the node's name unless it
/// already starts with it.
NodeError to_node_error(NodeId node, std::exception_ptr e) {
  std::string what;
  bool fits = true;
  try {
    std::rethrow_exception(e);
  } catch (const NodeError& ne) {
    return ne;
  } catch (const DoesNotFit& ex) {
    what = ex.what();
    fits = false;
  } catch (const std::exception& ex) {
    what = ex.what();
  } catch (...) {
    what = "unknown exception";
  }
  const std::string name = node_name(node);
  if (what.rfind(name + ":", 0) != 0) what = name + ": " + what;
  return NodeError(node, what, !fits);
}

NodeReport make_report(NodeContext& ctx, double clock, double wall) {
  NodeReport r;
  r.wall_s = wall;
  r.id = ctx.id();
  r.counters = ctx.counters();
  r.clock_s = clock;
  r.work_done_s = ctx.work_done_time();
  r.memory_peak = ctx.arena().peak();
  r.memory_budget = ctx.arena().budget();
  return r;
}

}  // namespace

namespace {

/// What every participant waits for (the watchdog's report): the nodes
/// that are not finished, at most 64 of them, then the host and the
/// scheduler.
std::string describe_waits(MachineState& state) {
  std::string out;
  std::size_t shown = 0, finished = 0;
  for (const auto& node : state.nodes) {
    if (!node) continue;  // run by another process
    if (state.finished[node->id()].load(std::memory_order_acquire)) {
      ++finished;
      continue;
    }
    if (shown++ < 64) out += node->describe_wait() + "; ";
  }
  if (shown > 64) out += fmt::format("... {} more; ", shown - 64);
  if (finished) out += fmt::format("{} nodes finished; ", finished);
  if (state.host) out += state.host->describe_wait() + "; ";
  out += state.scheduler->describe();
  return out;
}

/// Does this process run participant `id`?
bool runs_here(const MachineParams& params, NodeId id) {
  const Transport* t = params.transport;
  return !t || t->process_of(id, params.nodes) == t->process();
}

/// Builds the context of every node this process runs and the host's (their
/// mailboxes come out of their arenas), then runs `setup` on each of those
/// nodes. Throws NodeError naming the node that failed (does_not_fit when
/// its arena ran out).
void build_participants(MachineState& state, const MachineParams& params, const Machine::Main& setup) {
  const std::uint32_t n = params.nodes;
  try {
    for (NodeId i = 0; i < n; ++i)
      if (runs_here(params, i))
        state.nodes[i] =
            std::make_unique<NodeContext>(state, i, params.node_memory, params.mailbox_capacity, params.max_payload);
    if (runs_here(params, kHost))
      state.host = std::make_unique<NodeContext>(state, kHost, SIZE_MAX, params.host_mailbox_capacity,
                                                 params.max_payload);
    if (setup)
      for (NodeId i = 0; i < n; ++i) {
        if (!state.nodes[i]) continue;
        try {
          setup(*state.nodes[i]);
        } catch (...) {
          throw to_node_error(i, std::current_exception());
        }
      }
  } catch (const NodeError&) {
    throw;
  } catch (const ArenaExhausted& e) {
    throw NodeError(e.node, e.what(), true);
  }
}

/// Waits on `done` (under `lock`) until `all_done()`, watching the run: a
/// stall of --stall-timeout seconds without a message, a process-wide stop
/// request (core/stop.h) or the --timeout end it, failing it with the
/// reason and every participant's wait.
void watch_run(MachineState& state, const MachineParams& params, std::unique_lock<std::mutex>& lock,
               std::condition_variable& done, const std::function<bool()>& all_done) {
  using clock = std::chrono::steady_clock;
  const auto start = clock::now();
  auto last_change = start;
  std::uint64_t last_progress = state.progress.load(std::memory_order_relaxed);
  const double tick = params.stall_timeout_s > 0 ? std::min(0.1, params.stall_timeout_s / 4) : 0.1;
  std::string why;
  while (!done.wait_for(lock, std::chrono::duration<double>(tick), all_done)) {
    const auto now = clock::now();
    const std::uint64_t p = state.progress.load(std::memory_order_relaxed);
    if (p != last_progress) last_progress = p, last_change = now;
    const double stalled = std::chrono::duration<double>(now - last_change).count();
    if (params.stall_timeout_s > 0 && stalled >= params.stall_timeout_s) {
      why = fmt::format("no message was sent for {:.3g} s (watchdog, --stall-timeout)", stalled);
      break;
    }
    if (core::stop_requested()) {
      why = core::stop_message();
      break;
    }
    if (params.timeout_s > 0 && std::chrono::duration<double>(now - start).count() >= params.timeout_s) {
      why = fmt::format("the run did not finish within {} s (watchdog, --timeout)", params.timeout_s);
      break;
    }
  }
  if (!why.empty()) {
    lock.unlock();
    state.fail(kHost,
               std::make_exception_ptr(std::runtime_error(fmt::format("{}; stopped. {}", why, describe_waits(state)))));
  }
}

/// The report of a finished run: each participant's counters at its final
/// clock (`final_clock`: the nodes', then the host's), T_p, the scheduler's.
RunReport make_run_report(MachineState& state, const MachineParams& params, const std::vector<double>& final_clock,
                          const std::vector<double>& wall) {
  const std::uint32_t n = params.nodes;
  RunReport report;
  report.network = params.network.name;
  if (params.transport) report.transport = params.transport->name();
  report.contention = params.network.contention;
  report.topology = topology_name(params.topology);
  report.clock = compute_clock_name(params.clock);
  report.corun_slowdown = applied_corun_slowdown(params);
  report.work_requests = work_request_route_name(params.work_request_route);
  report.work_grants = work_grant_name(params.work_grant);
  report.nodes.resize(n);
  // A participant's ray credits received, as kControl messages (MachineState::credits_received).
  auto add_credits = [&](NodeReport& r, std::uint32_t slot) {
    if (!state.credits_received) return;
    const std::uint64_t k = state.credits_received[slot].load(std::memory_order_relaxed);
    MessageCounts& c = r.counters.received[std::size_t(MessageType::kControl)];
    c.messages += k;
    c.bytes += k * sizeof(std::int32_t);
  };
  for (NodeId i = 0; i < n; ++i) {
    if (state.nodes[i]) {
      report.nodes[i] = make_report(*state.nodes[i], final_clock[i], wall[i]);
      add_credits(report.nodes[i], i);
    } else {
      report.nodes[i].id = i;
    }
  }
  if (params.transport) gather_per_node(*params.transport, report.nodes);
  for (const NodeReport& nr : report.nodes)
    report.parallel_time_s = std::max(report.parallel_time_s, nr.work_done_s >= 0 ? nr.work_done_s : nr.clock_s);
  if (state.host) {
    report.host = make_report(*state.host, final_clock[n], wall[n]);
    add_credits(report.host, n);
  }
  report.compute_grants = state.scheduler->compute_grants();
  report.handoffs = state.scheduler->handoffs();
  report.service_grants = state.scheduler->service_grants();
  report.scheduled_mail = state.scheduler->scheduled_mail();
  return report;
}

/// The participant whose main runs on this thread (null on others).
thread_local NodeContext* t_participant = nullptr;

/// Hands a message that came through the transport to its participant's
/// mailbox, waiting while the mailbox is full (on the participant's own
/// thread, which polled for it: parked instead, NodeContext::accept); drops
/// it when the participant has finished (as a send to a finished node would
/// fail here) or the run stops.
void deliver_to(MachineState& state, NodeId dest, const MessageHeader& header, std::span<const std::byte> payload) {
  const bool known = dest == kHost ? state.host != nullptr : dest < state.params.nodes && state.nodes[dest];
  if (known && t_participant == &state.context(dest)) {
    t_participant->accept(header, payload);
    state.progress.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  auto gone = [&] {
    return state.stop.load(std::memory_order_acquire) ||
           (dest == kHost ? state.host_finished.load(std::memory_order_acquire)
                          : state.finished[dest].load(std::memory_order_acquire));
  };
  if (!known || gone()) return;
  const std::span<const std::byte> parts[1] = {payload};
  int spins = 0;
  while (!state.context(dest).mailbox().try_push(header, parts)) {
    if (gone()) return;
    if (++spins < 64) std::this_thread::yield();
    else std::this_thread::sleep_for(std::chrono::microseconds(50));
  }
  state.progress.fetch_add(1, std::memory_order_relaxed);
}

}  // namespace

RunReport Machine::run(const Main& node_main, const Main& host_main, const Main& setup, const Main& teardown) {
  const auto wall0 = std::chrono::steady_clock::now();
  MachineState state(params_);
  const std::uint32_t n = params_.nodes;
  Transport* const transport = params_.transport;
  // Runs teardown for every built node on every way out of this function.
  struct Teardown {
    MachineState& state;
    const Main& teardown;
    ~Teardown() {
      if (!teardown) return;
      for (auto& node : state.nodes) {
        if (!node) continue;
        try {
          teardown(*node);
        } catch (...) {
        }
      }
    }
  } teardown_guard{state, teardown};
  build_participants(state, params_, setup);
  // Receiving from the other processes, until finish() (or stop() on a failure).
  struct Receiving {
    Transport* transport;
    bool finished = false;
    ~Receiving() {
      if (transport && !finished) transport->stop();
    }
  } receiving{transport};
  if (transport)
    transport->start([&state](NodeId dest, const MessageHeader& h, std::span<const std::byte> payload) {
      if (h.type == MessageType::kControl && h.reserved == kRayCreditTag && payload.size() == sizeof(std::int32_t)) {
        std::int32_t count;
        std::memcpy(&count, payload.data(), sizeof count);
        state.ray_credit(dest, h.source).fetch_add(count, std::memory_order_release);
        state.credits_received[dest == kHost ? state.params.nodes : dest].fetch_add(1, std::memory_order_relaxed);
        state.progress.fetch_add(1, std::memory_order_relaxed);
        return;
      }
      deliver_to(state, dest, h, payload);
    });

  std::mutex done_mutex;
  std::condition_variable done_cv;
  std::vector<NodeId> local;
  for (NodeId i = 0; i < n; ++i)
    if (state.nodes[i]) local.push_back(i);
  if (state.host) local.push_back(kHost);
  const std::uint32_t participants = std::uint32_t(local.size());
  std::uint32_t running = participants;
  std::vector<double> final_clock(n + 1, 0.0), wall(n + 1, 0.0);
  auto participant = [&](NodeId id, const Main& main, std::size_t slot) {
    NodeContext& ctx = state.context(id);
    const auto start = std::chrono::steady_clock::now();
    t_participant = &ctx;
    // Under a transport the host shares its process's cores with a node of
    // its own, which it must not slow: it only gathers, and gets a core
    // whenever a node waits (or blocks on the host's full mailbox).
    if (id == kHost && transport) ::setpriority(PRIO_PROCESS, 0, 19);
    ctx.reset_cpu_mark();
    try {
      main(ctx);
    } catch (const RunAborted&) {
      // stopped because someone else failed
    } catch (...) {
      state.fail(id, std::current_exception());
    }
    t_participant = nullptr;
    final_clock[slot] = ctx.now();
    wall[slot] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ctx.note_wait(WaitReason::kDone);
    if (id != kHost) {
      state.scheduler->retire(id);
      state.finished[id].store(true, std::memory_order_release);
    } else {
      state.host_finished.store(true, std::memory_order_release);
    }
    {
      std::lock_guard<std::mutex> lock(done_mutex);
      --running;
    }
    done_cv.notify_all();
  };

  std::vector<std::thread> threads;
  threads.reserve(participants);
  try {
    for (NodeId id : local)
      threads.emplace_back(participant, id, std::cref(id == kHost ? host_main : node_main),
                           std::size_t(id == kHost ? n : id));
  } catch (...) {
    state.fail(kHost, std::current_exception());  // e.g. no more threads: stop those started
  }
  {
    std::unique_lock<std::mutex> lock(done_mutex);
    const std::uint32_t started = std::uint32_t(threads.size());
    auto all_done = [&] { return running <= participants - started; };
    watch_run(state, params_, lock, done_cv, all_done);
  }
  for (std::thread& t : threads) t.join();
  if (std::exception_ptr e = state.error()) throw to_node_error(state.error_node(), e);
  if (transport) {
    transport->finish();
    receiving.finished = true;
  }

  RunReport report = make_run_report(state, params_, final_clock, wall);
  report.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  return report;
}

NodeCounters RunReport::total() const {
  NodeCounters t;
  for (const NodeReport& r : nodes) t += r.counters;
  return t;
}

namespace {

// `every_type`: sent and received list every message type, zeros included
// (the run's totals: the same keys whatever the timing granted); else only
// the types with a message (the host and each node).
nlohmann::json counters_json(const NodeCounters& c, bool every_type) {
  nlohmann::json j;
  nlohmann::json sent = nlohmann::json::object(), received = nlohmann::json::object();
  for (std::size_t i = 0; i < kMessageTypeCount; ++i) {
    const char* name = message_type_name(MessageType(i));
    if (every_type || c.sent[i].messages)
      sent[name] = {{"messages", c.sent[i].messages}, {"bytes", c.sent[i].bytes}};
    if (every_type || c.received[i].messages)
      received[name] = {{"messages", c.received[i].messages}, {"bytes", c.received[i].bytes}};
  }
  const MessageCounts ts = c.total_sent();
  j["messages_sent"] = ts.messages;
  j["bytes_sent"] = ts.bytes;
  j["sent"] = sent;
  j["received"] = received;
  j["time"] = {{"busy_s", c.busy_s},
               {"idle_s", c.idle_s},
               {"communication_s", c.communication_s},
               {"emulator_overhead_cpu_s", c.overhead_cpu_s},
               {"idle_wall_s", c.idle_wall_s},
               {"communication_wall_s", c.communication_wall_s}};
  j["full_mailbox_retries"] = c.full_mailbox_retries;
  j["mail_checks"] = c.mail_checks;
  j["services"] = c.services;
  j["service_wait_s"] = c.service_wait_s;
  j["link_waits"] = c.link_waits;
  j["link_wait_s"] = c.link_wait_s;
  j["backlog_peak"] = c.backlog_peak;
  return j;
}

}  // namespace

nlohmann::json RunReport::to_json(bool per_node) const {
  nlohmann::json j;
  j["count"] = nodes.size();
  j["network"] = network;
  j["contention"] = contention;
  j["topology"] = topology;
  j["clock"] = clock;
  j["corun_slowdown"] = corun_slowdown;
  j["work_requests"] = work_requests;
  j["work_grants"] = work_grants;
  j["parallel_time_s"] = parallel_time_s;
  j["wall_s"] = wall_s;
  if (!transport.empty()) j["transport"] = transport;
  j["scheduler"] = {{"compute_grants", compute_grants},
                    {"handoffs", handoffs},
                    {"service_grants", service_grants},
                    {"mail", scheduled_mail ? "scheduled" : "immediate"}};
  std::size_t peak = 0;
  for (const NodeReport& r : nodes) peak = std::max(peak, r.memory_peak);
  j["memory_peak_bytes"] = peak;
  j["memory_budget_bytes"] = nodes.empty() ? 0 : nodes.front().memory_budget;
  j["total"] = counters_json(total(), true);
  j["host"] = counters_json(host.counters, false);
  if (per_node) {
    nlohmann::json arr = nlohmann::json::array();
    for (const NodeReport& r : nodes) {
      nlohmann::json e = counters_json(r.counters, false);
      e["id"] = r.id;
      e["clock_s"] = r.clock_s;
      e["work_done_s"] = r.work_done_s;
      e["memory_peak_bytes"] = r.memory_peak;
      e["wall_s"] = r.wall_s;
      arr.push_back(std::move(e));
    }
    j["per_node"] = std::move(arr);
  }
  return j;
}

ComputeClock parse_compute_clock(const std::string& text) {
  if (text == "cpu") return ComputeClock::kCpu;
  if (text == "model") return ComputeClock::kModel;
  throw std::invalid_argument("the clock must be cpu or model, got '" + text + "'");
}

const char* compute_clock_name(ComputeClock c) { return c == ComputeClock::kModel ? "model" : "cpu"; }

WorkRequestRoute parse_work_request_route(const std::string& text) {
  if (text == "ring") return WorkRequestRoute::kRing;
  if (text == "last-grantor") return WorkRequestRoute::kLastGrantor;
  if (text == "off") return WorkRequestRoute::kOff;
  throw std::invalid_argument("work requests go by ring or last-grantor, or are off, got '" + text + "'");
}

const char* work_request_route_name(WorkRequestRoute r) {
  switch (r) {
    case WorkRequestRoute::kLastGrantor: return "last-grantor";
    case WorkRequestRoute::kOff: return "off";
    case WorkRequestRoute::kRing: break;
  }
  return "ring";
}

WorkGrant parse_work_grant(const std::string& text) {
  if (text == "item") return WorkGrant::kItem;
  if (text == "half") return WorkGrant::kHalf;
  if (text == "nearest") return WorkGrant::kNearest;
  if (text == "auto") return WorkGrant::kAuto;
  throw std::invalid_argument("work grants are auto, item, nearest or half, got '" + text + "'");
}

WorkGrant resolved_work_grant(const MachineParams& params) {
  if (params.work_grant != WorkGrant::kAuto) return params.work_grant;
  return params.transport ? WorkGrant::kHalf : WorkGrant::kItem;
}

const char* work_grant_name(WorkGrant g) {
  switch (g) {
    case WorkGrant::kHalf: return "half";
    case WorkGrant::kNearest: return "nearest";
    case WorkGrant::kAuto: return "auto";
    case WorkGrant::kItem: break;
  }
  return "item";
}

std::size_t parse_bytes(const std::string& text) {
  std::size_t i = 0;
  while (i < text.size() && std::isdigit(static_cast<unsigned char>(text[i]))) ++i;
  if (i == 0) throw std::invalid_argument("'" + text + "' is not a byte size (e.g. 4MiB, 512KiB, 65536)");
  std::string unit = text.substr(i);
  for (char& ch : unit) ch = char(std::tolower(static_cast<unsigned char>(ch)));
  std::size_t mult = 0;
  if (unit.empty() || unit == "b") mult = 1;
  else if (unit == "k" || unit == "kib" || unit == "kb") mult = std::size_t(1) << 10;
  else if (unit == "m" || unit == "mib" || unit == "mb") mult = std::size_t(1) << 20;
  else if (unit == "g" || unit == "gib" || unit == "gb") mult = std::size_t(1) << 30;
  if (mult == 0) throw std::invalid_argument("'" + text + "' has an unknown unit (B, KiB, MiB, GiB)");
  // Digit by digit, stopping before the value overflows (any number of digits).
  std::uint64_t value = 0;
  bool overflow = false;
  for (std::size_t k = 0; k < i; ++k) {
    const unsigned d = unsigned(text[k] - '0');
    if (value > (UINT64_MAX - d) / 10) {
      overflow = true;
      break;
    }
    value = value * 10 + d;
  }
  if (!overflow && value > kMaxByteSize / mult) overflow = true;
  if (overflow)
    throw std::invalid_argument(fmt::format("byte size '{}' is too large: at most {} GiB ({} B)", text,
                                            kMaxByteSize >> 30, kMaxByteSize));
  if (value == 0) throw std::invalid_argument("byte size '" + text + "' must be > 0");
  return std::size_t(value) * mult;
}

std::size_t host_physical_memory() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
  if (pages <= 0 || page <= 0) return 0;
  return std::size_t(pages) * std::size_t(page);
}

void check_nodes_fit_host(std::uint32_t nodes, std::size_t node_memory, std::size_t host_bytes) {
  if (host_bytes == 0) return;  // unknown: nothing to check against
  const unsigned __int128 total = (unsigned __int128)nodes * node_memory;
  if (total <= host_bytes) return;
  const double total_gib = double(total) / double(std::size_t(1) << 30);
  throw std::invalid_argument(fmt::format(
      "--nodes {} x --node-memory {} = {:.6g} GiB, more than this host's {} of physical memory: a node's budget "
      "must be memory the host has, or the host runs out before any node's arena refuses; use fewer nodes or "
      "less --node-memory",
      nodes, format_bytes(node_memory), total_gib, format_bytes(host_bytes)));
}

}  // namespace raynode::nodes
