#include "nodes/network.h"

#include <algorithm>
#include <stdexcept>

#include "core/database.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/spd.h"
#include "nodes/cpu_time.h"

namespace raynode::nodes {

NetworkModel make_network(const std::string& name, double seconds_per_ray, const core::CostModel* model) {
  NetworkModel m;
  m.name = name;
  if (name == "none") return m;
  if (name == "ipsc2") {
    if (seconds_per_ray <= 0) seconds_per_ray = model ? model_seconds_per_ray(*model) : calibrate_seconds_per_ray();
    m.scale = seconds_per_ray / kIpsc2SecondsPerRay;
    const double peak = 2.75e6, rate_1k = 0.9e6;
    m.per_byte_s = m.scale / peak;
    // The start-up read from the paper's figures, less the message
    // software's CPU time at the sender (kIpsc2SendOverheadS).
    m.send_overhead_s = m.scale * kIpsc2SendOverheadS;
    m.latency_s = m.scale * (1024.0 / rate_1k - 1024.0 / peak - kIpsc2SendOverheadS);
    m.per_hop_s = m.scale * 10e-6;
    m.service_s = m.scale * 100e-6;
    m.fault_s = m.service_s;
    m.contention = true;  // Direct-Connect circuits hold their links while a message streams (links.h)
    return m;
  }
  if (name == "cluster") {
    m.latency_s = 1.5e-6;
    m.per_byte_s = 1.0 / 12.5e9;
    m.per_hop_s = 0.1e-6;
    m.service_s = 0.5e-6;
    return m;
  }
  throw std::invalid_argument("unknown network '" + name + "' (none, ipsc2, cluster)");
}

namespace {

/// Renders the calibration image (teapot:8, 64x64, one thread) `repeat`
/// times; returns the least CPU seconds per ray and the counters.
double calibration_render(int repeat, core::RenderStats& stats) {
  const core::Scene scene = core::make_spd_scene(core::SpdParams{"teapot", 8, 0});
  const core::Database db = core::make_database(scene);
  const core::Grid grid = core::build_grid(db);
  core::RenderParams params;
  params.width = params.height = 64;
  double best = 1e30;
  for (int rep = 0; rep < repeat; ++rep) {
    const double t0 = thread_cpu_seconds();
    const core::RenderResult r = core::render(db, grid, params);
    const double dt = thread_cpu_seconds() - t0;
    best = std::min(best, dt / double(std::max<std::uint64_t>(1, r.stats.rays.total())));
    stats = r.stats;
  }
  return best;
}

}  // namespace

double calibrate_seconds_per_ray() {
  core::RenderStats stats;
  return calibration_render(3, stats);
}

double model_seconds_per_ray(const core::CostModel& model) {
  core::RenderStats stats;
  calibration_render(1, stats);
  return model.seconds(stats.rays, stats.traversal) / double(std::max<std::uint64_t>(1, stats.rays.total()));
}

}  // namespace raynode::nodes
