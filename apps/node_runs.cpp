#include "apps/node_runs.h"

#include <fmt/core.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <tuple>
#include <vector>

#include "apps/commands.h"
#include "control/replicated.h"
#include "core/cost_model.h"
#include "core/spd.h"
#include "nodes/cpu_time.h"
#include "nodes/topology.h"
#include "svm/svm.h"

namespace raynode::apps {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void add_node_run_options(CLI::App& c, NodeRunOptions& o, NodeRunOptionSet set) {
  // First: CLI11 runs the callbacks of given options in the order they were
  // added, so the options below, when given, override the description.
  c.add_option_function<std::string>(
       "--machine",
       [&o](const std::string& name) {
         const MachineDescription m = load_machine(name);
         o.machine = m.name;
         if (m.node_memory) o.node_memory = *m.node_memory;
         if (m.page_size) o.page_size = *m.page_size;
         if (m.topology) o.topology = *m.topology;
         if (m.clock) o.clock = *m.clock;
         if (m.corun_slowdown) o.corun_slowdown = *m.corun_slowdown;
         if (m.cost_model) o.cost_model = *m.cost_model;
         if (m.network) o.network = *m.network;
         if (m.network_figures) o.network = "custom", o.network_figures = *m.network_figures;
       },
       "Node modes: the emulated machine from a description: ipsc2 (the paper's: 4 MiB nodes, 1 KiB pages, "
       "hypercube, model clock, ipsc2 network) or a JSON file (docs/machines/: node_memory, page_size, topology, "
       "clock, network as a preset or its figures); the other machine options, given, override it")
      ->type_name("NAME|FILE");
  if (set.experiment) {
    add_grid_option(c, o.grid);
    add_skip_empty_option(c, o.skip_empty);
    c.add_option("--width", o.width, "Image width in pixels")->check(CLI::Range(1, 16384))->capture_default_str();
    c.add_option("--height", o.height, "Image height in pixels")->check(CLI::Range(1, 16384))->capture_default_str();
  }
  c.add_option("--node-memory", o.node_memory,
               "Node modes: memory budget per node (B, KiB, MiB, GiB; the iPSC/2 node had 4 MiB)")
      ->capture_default_str();
  c.add_option("--network", o.network,
               "Node modes: network cost model for virtual time: ipsc2 (the paper's iPSC/2 scaled to this machine's "
               "ray speed, calibrated once per command), none (free), cluster (1.5 us, 12.5 GB/s)")
      ->check(CLI::IsMember({"none", "ipsc2", "cluster"}))
      ->capture_default_str();
  c.add_option("--contention", o.contention,
               "Node modes: link contention: on (a message holds its route's links while it streams, e-cube routes "
               "on the hypercube; the ipsc2 network's default), off (links never busy); default: the network's")
      ->check(CLI::IsMember({"auto", "on", "off"}))
      ->capture_default_str();
  c.add_option("--network-scale", o.network_scale,
               "ipsc2: this machine's seconds per ray (default: measured once at start)")
      ->check(finite_positive());
  c.add_option("--topology", o.topology, "Node modes: interconnect: hypercube (iPSC/2), ring, torus")
      ->check(CLI::IsMember({"hypercube", "ring", "torus"}))
      ->capture_default_str();
  c.add_option("--work-item", o.work_item, "replicated, svm: pixels per work item, WxH")->capture_default_str();
  c.add_option("--work-requests", o.work_requests,
               "replicated, svm: where an idle node asks for work: ring (the paper: to its ring successor, on round "
               "the ring), last-grantor (first straight to the node that gave it its last item, then the ring: "
               "fewer hops) or off (no requests: each node renders its static submap and nothing else, the "
               "baseline that shows what the requests gain)")
      ->check(CLI::IsMember({"ring", "last-grantor", "off"}))
      ->capture_default_str();
  c.add_option("--work-grants", o.work_grants,
               "replicated, svm: what a busy node grants a work request: item (the paper: one work item from the "
               "far end of its submap), nearest (one work item, the one nearest the requester's last), half (the "
               "far half of its remaining item rows as one rectangle that the requester renders as its new "
               "submap: a requester's pixels stay together, so svm's pages serve more of them) or auto (item in "
               "the emulator; half on MPI ranks, where every grant is a real round trip)")
      ->check(CLI::IsMember({"auto", "item", "nearest", "half"}))
      ->capture_default_str();
  c.add_option("--submaps", o.submaps,
               "replicated, svm: the nodes' static submaps: square (the paper: near-square parts of equal area) or "
               "balanced (parts of near-equal cost, estimated by tracing one pixel per --subsample block on the "
               "host first)")
      ->check(CLI::IsMember({"square", "balanced"}))
      ->capture_default_str();
  c.add_option("--subsample", o.subsample,
               "dataflow, and replicated/svm with --submaps balanced: the load estimate traces one pixel per NxN "
               "block (8 = the paper's 1.5%)")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  c.add_option("--schedule-window", o.schedule_window_us,
               "Node modes: virtual-time scheduling window in microseconds: a node this far ahead of a waiting one "
               "hands the CPU over (smaller = closer to a real parallel machine, more thread switches; negative = "
               "off, the OS schedules the node threads)")
      ->check(finite_range(-kNoBound, kNoBound))
      ->capture_default_str();
  c.add_option("--mail-wakeups", o.mail_wakeups, kMailWakeupsHelp)
      ->check(CLI::IsMember({"auto", "scheduled", "immediate"}))
      ->capture_default_str();
  c.add_option("--clock", o.clock,
               "Node modes: what advances a node's virtual clock while it computes: cpu (its thread's CPU time) or "
               "model (operation counts x calibrated unit costs: repeatable, free of the host's thread switches; "
               "see `raynode bench cost-model`)")
      ->check(CLI::IsMember({"cpu", "model"}))
      ->capture_default_str();
  c.add_option("--corun-slowdown", o.corun_slowdown,
               "Model clock, more than one node: a node's work costs this many times its one-node price (nodes "
               "sharing a host's cores, caches and memory bandwidth, as MPI ranks on one machine; `raynode bench mpi` "
               "measures it); 1 for nodes that share nothing")
      ->check(finite_range(1, nodes::kMaxCorunSlowdown))
      ->capture_default_str();
  c.add_option("--calibrate", o.calibrate,
               "Model clock: time a quarter-resolution sample of the scene with the sequential tracer before the "
               "runs and compare it with the model's seconds; auto scales every unit cost by CPU / model when they "
               "differ by more than 15%, on always, off never (the stats say which)")
      ->check(CLI::IsMember({"auto", "on", "off"}))
      ->capture_default_str();
  c.add_option("--stall-timeout", o.stall_timeout_s,
               "Node modes: stop with an error naming what each node waits for when no message was sent for this "
               "many wall seconds (0 = never)")
      ->check(finite_range(0, 1e9))
      ->capture_default_str();
  if (set.experiment) {
    c.add_option("--timeout", o.timeout_s, "Stop a run with an error after this many wall seconds (0 = never)")
        ->check(finite_range(0, kNoBound));
    c.add_option("--repeat", o.repeat, "Runs per point; the one with the lowest T_p is kept (best of)")
        ->check(CLI::Range(1, 100))
        ->capture_default_str();
    add_shadow_rays_option(c, o.shadow_rays);
  }
  if (set.page_size) {
    c.add_option("--page-size", o.page_size,
                 "svm: bytes per page of the shared virtual memory, a power of two from 64 (the paper: 1024)")
        ->capture_default_str();
    c.add_option("--directory-order", o.directory_order, kDirectoryOrderHelp)
        ->check(CLI::IsMember({"auto", "linear", "bricked"}))
        ->capture_default_str();
    c.add_option("--primitive-order", o.primitive_order, kPrimitiveOrderHelp)
        ->check(CLI::IsMember({"auto", "file", "cell"}))
        ->capture_default_str();
  }
  if (set.cache)
    c.add_option("--cache", o.cache,
                 "svm: page cache per node, N pages or P% of the database's pages (default: all the memory a node "
                 "has left after its home pages, page table and mailbox)");
  if (set.dataflow) {
    c.add_option("--partition", o.partition,
                 "dataflow: balanced (median cuts on the estimated load, the paper's method) or equal (equal-size "
                 "regions, the paper's comparison)")
        ->check(CLI::IsMember({"balanced", "equal"}))
        ->capture_default_str();
    c.add_option("--queue-capacity", o.queue_capacity,
                 "dataflow: slots of each node's mailbox (default 1024); a ray for a full mailbox goes to the host, "
                 "which forwards it later (1 forces spills)")
        ->check(CLI::Range(1, 1 << 20));
    c.add_option("--send-queue", o.send_queue,
                 "dataflow: slots of each node's sending queue, where a ray waits while its destination's mailbox "
                 "is full; a ray that finds this queue full goes to the host (the paper's \"optimistic\" deadlock "
                 "avoidance). Default: all the node memory its region and buffers leave, as the paper's message "
                 "queues took; with --queue-capacity 1, --send-queue 1 forces spills")
        ->check(CLI::Range(1, 1 << 30));
  }
}

void parse_cache(const std::string& text, std::uint32_t& pages, double& fraction) {
  if (text.empty()) return;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  const std::string rest(end ? end : "");
  if (end == text.c_str() || !(rest.empty() || rest == "%") || !std::isfinite(v))
    throw UsageError("--cache must be a page count (e.g. 200) or a percentage of the database (e.g. 10%), got '" +
                     text + "'");
  if (rest == "%") {
    if (!(v > 0 && v <= 100)) throw UsageError("--cache percentage must be in (0, 100], got '" + text + "'");
    fraction = v / 100.0;
  } else {
    if (!(v >= 1 && v <= 4294967295.0) || v != std::floor(v))
      throw UsageError("--cache must be a whole number of pages from 1 to 4294967295, or a percentage, got '" + text +
                       "'");
    pages = std::uint32_t(v);
  }
}

std::pair<int, int> parse_work_item(const std::string& text) {
  int w = 0, h = 0;
  char x = 0, extra = 0;
  if (std::sscanf(text.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || (x != 'x' && x != 'X') || w < 1 || h < 1 ||
      w > 256 || h > 256)
    throw UsageError("--work-item must be WxH with 1 <= W, H <= 256 (e.g. 3x3), got '" + text + "'");
  return {w, h};
}

NodeRunSpec make_node_run_spec(const NodeRunOptions& o) {
  NodeRunSpec s;
  s.render.width = o.width;
  s.render.height = o.height;
  s.render.shadow_rays = shadow_rays_from_name(o.shadow_rays);
  nodes::MachineParams& m = s.machine;
  try {
    m.node_memory = nodes::parse_bytes(o.node_memory);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--node-memory: ") + e.what());
  }
  try {
    m.topology = nodes::parse_topology(o.topology);
    m.clock = nodes::parse_compute_clock(o.clock);
    m.work_request_route = nodes::parse_work_request_route(o.work_requests);
    m.work_grant = nodes::parse_work_grant(o.work_grants);
    s.submaps.rule = control::parse_submap_rule(o.submaps);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--topology/--clock/--work-requests/--work-grants/--submaps: ") + e.what());
  }
  m.corun_slowdown = o.corun_slowdown;
  if (o.cost_model) m.cost_model = *o.cost_model;
  m.timeout_s = o.timeout_s;
  m.stall_timeout_s = o.stall_timeout_s;
  m.schedule_window_s = o.schedule_window_us * 1e-6;
  if (o.mail_wakeups != "auto") m.scheduled_mail = o.mail_wakeups == "scheduled";
  if (o.network == "custom" && o.network_figures) {
    // A described network: its figures, scaled to this host's tracing speed
    // when the description gives its own (as the ipsc2 preset is scaled).
    const NetworkFigures& f = *o.network_figures;
    double scale = 1;
    if (f.seconds_per_ray > 0) {
      const double here = o.network_scale > 0                           ? o.network_scale
                          : m.clock == nodes::ComputeClock::kModel ? nodes::model_seconds_per_ray(m.cost_model)
                                                                   : nodes::calibrate_seconds_per_ray();
      scale = here / f.seconds_per_ray;
    }
    m.network.name = o.machine;
    m.network.scale = scale;
    m.network.latency_s = scale * f.latency_s;
    m.network.per_byte_s = scale * f.per_byte_s;
    m.network.per_hop_s = scale * f.per_hop_s;
    m.network.service_s = scale * f.service_s;
    m.network.fault_s = f.fault_s < 0 ? -1.0 : scale * f.fault_s;
    m.network.cache_access_s = f.cache_access_s < 0 ? -1.0 : scale * f.cache_access_s;
    m.network.send_overhead_s = scale * f.send_overhead_s;
    m.network.poll_s = scale * f.poll_s;
    m.network.contention = f.contention;
  } else {
    try {
      m.network = nodes::make_network(o.network, o.network_scale,
                                      m.clock == nodes::ComputeClock::kModel ? &m.cost_model : nullptr);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--network: ") + e.what());
    }
  }
  if (o.contention != "auto") m.network.contention = o.contention == "on";
  std::tie(s.item_w, s.item_h) = parse_work_item(o.work_item);
  if (o.page_size < svm::kMinPageSize || o.page_size > svm::kMaxPageSize || !std::has_single_bit(o.page_size))
    throw UsageError(fmt::format("--page-size: page size must be a power of two from {} B (one primitive record) "
                                 "to {} B, got {} B",
                                 svm::kMinPageSize, svm::kMaxPageSize, o.page_size));
  s.page_size = o.page_size;
  try {
    s.directory_order = svm::parse_directory_order(o.directory_order);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--directory-order: ") + e.what());
  }
  try {
    s.primitive_order = svm::parse_primitive_order(o.primitive_order);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--primitive-order: ") + e.what());
  }
  parse_cache(o.cache, s.cache_pages, s.cache_fraction);
  s.subsample = o.subsample;
  s.submaps.subsample = o.subsample;
  s.partition = dataflow::parse_partition(o.partition);
  s.queue_capacity = o.queue_capacity;
  s.send_queue = o.send_queue;
  s.repeat = o.repeat;
  return s;
}

namespace {

/// True for the failures that mean "this configuration does not fit a
/// node's memory": a mode's check before a run, or a node that ran out of
/// its memory inside one (nodes::DoesNotFit, typed: no message is read).
bool is_fit_error(const std::exception& e) {
  if (const auto* ne = dynamic_cast<const nodes::NodeError*>(&e)) return ne->does_not_fit;
  return dynamic_cast<const nodes::DoesNotFit*>(&e) != nullptr;
}

double busy_sum(const nodes::RunReport& run) {
  double s = 0;
  for (const nodes::NodeReport& n : run.nodes) s += n.counters.busy_s;
  return s;
}

std::uint64_t grants_sum(const std::vector<control::WorkStats>& work) {
  std::uint64_t g = 0;
  for (const control::WorkStats& w : work) g += w.grants_given;
  return g;
}

/// The balanced submaps' host estimate in the run's clock's seconds;
/// nullopt for square submaps.
std::optional<double> estimate_seconds(const control::SubmapPlan& plan, nodes::ComputeClock clock) {
  if (plan.params.rule != control::SubmapRule::kBalanced) return std::nullopt;
  return clock == nodes::ComputeClock::kModel ? plan.estimate.model_s : plan.estimate.wall_s;
}

/// The NodeRun of a finished run `r` in `mode`: T_p, work, rays and the mode's own figures.
NodeRun summarise(const modes::RunResult& r, modes::Mode mode, nodes::ComputeClock clock) {
  NodeRun out;
  const nodes::RunReport& run = *r.run();
  out.parallel_time_s = run.parallel_time_s;
  out.work_s = busy_sum(run);
  out.rays = r.render.stats.rays.total();
  out.mail_checks = run.total().mail_checks;
  if (const std::vector<control::WorkStats>* work = r.work()) out.grants = grants_sum(*work);
  if (r.replicated) out.estimate_s = estimate_seconds(r.replicated->submaps, clock);
  if (mode == modes::Mode::kSvm) {
    const svm::SvmResult& s = *r.svm;
    out.estimate_s = estimate_seconds(s.submaps, clock);
    const svm::PagerStats t = s.pager_total();
    out.miss_ratio = t.miss_ratio();
    out.cache_miss_ratio = t.cache_miss_ratio();
    out.pages_per_pixel = t.pages_per_pixel();
    out.accesses = t.accesses;
    out.cache_page_accesses = t.cache_page_accesses;
    out.evictions = t.evictions;
    const nodes::NodeCounters c = run.total();
    out.page_requests = c.sent[std::size_t(nodes::MessageType::kPageRequest)].messages;
    const std::uint64_t page_bytes = c.received[std::size_t(nodes::MessageType::kPageReply)].bytes;
    out.communication_rate_bytes_per_s = run.parallel_time_s > 0 ? double(page_bytes) / run.parallel_time_s : 0.0;
    out.cache_pages = s.pager.empty() ? 0u : s.pager.front().cache_pages;
    out.pages_total = s.layout.pages;
    out.database_bytes = s.layout.bytes();
  } else if (mode == modes::Mode::kDataflow) {
    out.ray_messages = r.dataflow->ray_messages();
    out.spill_fraction = r.dataflow->spill_fraction();
    out.average_load = r.dataflow->average_load();
  }
  return out;
}

}  // namespace

NodeRun run_node_mode(const core::Database& db, const core::Grid& grid, const std::string& mode,
                      const NodeRunSpec& spec, std::uint32_t node_count, std::size_t node_memory) {
  modes::RunRequest req;
  try {
    req.mode = modes::parse_mode(mode);
    if (!modes::is_node_mode(req.mode)) throw std::invalid_argument(mode);
  } catch (const std::invalid_argument&) {
    throw UsageError("unknown node mode '" + mode + "' (replicated, svm, dataflow)");
  }
  req.render = spec.render;
  req.nodes = spec;
  req.nodes.machine.nodes = node_count;
  if (node_memory > 0) req.nodes.machine.node_memory = node_memory;
  const auto t0 = std::chrono::steady_clock::now();
  NodeRun out;
  try {
    out = summarise(modes::render(db, &grid, req), req.mode, req.nodes.machine.clock);
  } catch (const std::invalid_argument& e) {
    throw UsageError(mode + " mode: " + e.what());
  } catch (const std::exception& e) {
    if (!is_fit_error(e)) throw;
    out = NodeRun{};
    out.fits = false;
    out.skipped = e.what();
  }
  out.node_memory = req.nodes.machine.node_memory;
  out.wall_s = seconds_since(t0);
  return out;
}

NodeRun run_best(const core::Database& db, const core::Grid& grid, const std::string& mode, const NodeRunSpec& spec,
                 std::uint32_t node_count, std::size_t node_memory) {
  NodeRun best;
  for (int i = 0; i < std::max(1, spec.repeat); ++i) {
    NodeRun r = run_node_mode(db, grid, mode, spec, node_count, node_memory);
    if (!r.fits) return r;
    if (i == 0 || r.parallel_time_s < best.parallel_time_s) best = std::move(r);
  }
  return best;
}

std::string format_duration(double s) {
  if (!(s >= 0) || !std::isfinite(s)) return "?";
  if (s < 60) return fmt::format("{:.1f} s", s);
  const long t = std::lround(s);
  if (t < 3600) return fmt::format("{} min {:02} s", t / 60, t % 60);
  return fmt::format("{} h {:02} min", t / 3600, (t % 3600) / 60);
}

nlohmann::json ModelCalibration::to_json() const {
  if (!measured) return nullptr;
  return {{"sample", {kCalibrationSample, kCalibrationSample}},
          {"cpu_s", cpu_s},
          {"model_s", model_s},
          {"reference", {{"scene", "teapot:8"}, {"cpu_s", reference_cpu_s}, {"model_s", reference_model_s}}},
          {"error", ratio - 1},
          {"applied", applied},
          {"same_work", same_work},
          {"threshold", kCalibrateAbove}};
}

namespace {

/// One sequential render of `db` at kCalibrationSample pixels square: its
/// thread CPU seconds, the model's seconds for its operation counts, and
/// the counts.
struct Sample {
  double cpu_s = 0, model_s = 0;
  core::CostCounts counts{};
};

Sample time_sample(const core::Database& db, const core::Grid& grid, const core::RenderParams& render,
                   const core::CostModel& model) {
  core::RenderParams p;
  p.width = p.height = kCalibrationSample;
  p.spp = render.spp;
  p.max_depth = render.max_depth;
  p.min_weight = render.min_weight;
  p.shadow_rays = render.shadow_rays;
  const double t0 = nodes::thread_cpu_seconds();
  const core::RenderResult r = core::render(db, grid, p);
  const double cpu = nodes::thread_cpu_seconds() - t0;
  const core::CostCounts counts = core::cost_counts(r.stats.rays, r.stats.traversal);
  return {cpu, model.seconds(counts), counts};
}

}  // namespace

std::string ModelCalibration::summary() const {
  return fmt::format("model clock: {:+.0f}% against Teapot on this host{}", 100 * (ratio - 1),
                     applied ? ", unit costs scaled by it (--calibrate)" : "");
}

ModelCalibration calibrate_model_clock(nodes::MachineParams& machine, const core::RenderParams& render,
                                       const core::Database& db, const core::Grid& grid, const std::string& policy) {
  ModelCalibration c;
  if (machine.clock != nodes::ComputeClock::kModel || policy == "off") return c;
  // The reference: the scene the network's scale is measured on (nodes::
  // model_seconds_per_ray), so that the model's seconds stay Teapot's;
  // loaded as the commands load a scene (rendering space), so that teapot:8
  // given as the scene does exactly the reference's work.
  const core::Scene teapot = core::load_scene(tracing_source("teapot:8"));
  const core::Database tdb = core::make_database(teapot);
  const core::Grid tgrid = core::build_grid(tdb);
  // A first, untimed sample of each warms the caches and gives the counts.
  const Sample first = time_sample(db, grid, render, machine.cost_model);
  const Sample ref_first = time_sample(tdb, tgrid, render, machine.cost_model);
  c.model_s = first.model_s;
  c.reference_model_s = ref_first.model_s;
  if (!(c.model_s > 0 && c.reference_model_s > 0)) return c;
  if (first.counts == ref_first.counts) {
    // The reference's own work (teapot:8 itself): no error by definition,
    // where timing it against itself would measure only the host's noise.
    c.same_work = true;
    c.cpu_s = first.cpu_s;
    c.reference_cpu_s = first.cpu_s;
  } else {
    // Rounds of the scene then the reference, back to back: each round's
    // ratio sees the host's speed of that moment in both samples, and the
    // median round's ignores the rounds a burst of load hit.
    struct Round {
      double ratio, cpu_s, reference_cpu_s;
    };
    std::vector<Round> rounds;
    for (int i = 0; i < kCalibrationRounds; ++i) {
      const double cpu = time_sample(db, grid, render, machine.cost_model).cpu_s;
      const double ref_cpu = time_sample(tdb, tgrid, render, machine.cost_model).cpu_s;
      if (cpu > 0 && ref_cpu > 0)
        rounds.push_back({(cpu / c.model_s) / (ref_cpu / c.reference_model_s), cpu, ref_cpu});
    }
    if (rounds.empty()) return c;
    const auto median = rounds.begin() + std::ptrdiff_t(rounds.size() / 2);
    std::nth_element(rounds.begin(), median, rounds.end(),
                     [](const Round& a, const Round& b) { return a.ratio < b.ratio; });
    c.cpu_s = median->cpu_s;
    c.reference_cpu_s = median->reference_cpu_s;
  }
  c.measured = true;
  c.ratio = (c.cpu_s / c.model_s) / (c.reference_cpu_s / c.reference_model_s);
  c.applied = policy == "on" || std::abs(c.ratio - 1) > kCalibrateAbove;
  if (c.applied)
    for (double& u : machine.cost_model.unit_s) u *= c.ratio;
  return c;
}

double node_round_trip_s(nodes::MachineParams p, std::size_t bytes, std::uint64_t trips) {
  p.max_payload = std::max(p.max_payload, std::uint32_t(bytes));
  nodes::Machine machine(p);
  double seconds = 0;
  const std::vector<std::byte> payload(bytes);
  const std::span<const std::byte> part[1] = {payload};
  const std::span<const std::span<const std::byte>> parts(part, 1);
  machine.run(
      [&](nodes::NodeContext& ctx) {
        if (ctx.id() > 1) return;
        const nodes::NodeId other = 1 - ctx.id();
        const auto t0 = std::chrono::steady_clock::now();
        for (std::uint64_t i = 0; i < trips; ++i) {
          if (ctx.id() == 0) {
            ctx.send(other, nodes::MessageType::kTest, parts);
            ctx.receive(nodes::WaitKind::kIdle);
          } else {
            ctx.receive(nodes::WaitKind::kIdle);
            ctx.send(other, nodes::MessageType::kTest, parts);
          }
        }
        if (ctx.id() == 0) seconds = seconds_since(t0);
      },
      [](nodes::NodeContext&) {});
  return seconds / double(trips);
}

std::string hours_minutes_seconds(double s) {
  if (!(s >= 0) || !std::isfinite(s)) return "?";
  const long long t = std::llround(s);
  return fmt::format("{}:{:02}:{:02}", t / 3600, (t % 3600) / 60, t % 60);
}

}  // namespace raynode::apps
