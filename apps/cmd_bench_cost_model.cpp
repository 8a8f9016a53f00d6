// `raynode bench cost-model`: fits the model clock's unit costs
// (core/cost_model.h) on this machine and prints them with the quality of
// the fit. Nothing here is a pass/fail check.
//
// Method: each scene is rendered by the sequential tracer, one thread, in
// 8x8-pixel tiles; each tile's CPU time (least of --repeat passes) and its
// operation counts make one sample; the tracer's unit costs are the
// non-negative least-squares fit of time on counts, relative error. The
// pager's costs (page access, cache access) are then fitted on tiles
// rendered the same way through svm's pager and PagedView on node 0 of a
// one- and a two-node machine, every page cached (see pager_samples); the
// fault's own cost is modelled, not fitted: see cost_model.h.
#include <fmt/core.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include "apps/commands.h"
#include "core/cost_model.h"
#include "core/database.h"
#include "core/direct_view.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/scene_source.h"
#include "nodes/cpu_time.h"
#include "nodes/machine.h"
#include "svm/paged_database.h"
#include "svm/paged_view.h"
#include "svm/pager.h"

namespace raynode::apps {

namespace {

struct CostModelOptions {
  std::vector<std::string> scenes{"teapot:8", "mount:6", "rings:4", "rings:4@1", "tetra:8", "balls:3"};
  int width = 128, height = 128;
  int repeat = 3;
  bool pager = true;
  std::vector<std::string> fit;  ///< features to fit; empty: all
  GridChoice grid;               ///< --grid (default adaptive)
  bool quiet = false;            ///< -q: no progress lines
};

/// "name:size@R" -> SceneSource with --tessellate R, in render's space.
core::SceneSource parse_scene(const std::string& text) {
  const std::size_t at = text.find('@');
  core::SceneSource s = tracing_source(text.substr(0, at));
  if (at != std::string::npos) {
    try {
      s.tessellate = std::stoi(text.substr(at + 1));
    } catch (const std::exception&) {
      throw UsageError("--scenes: '" + text + "' is not SCENE or SCENE@R (R = tessellation)");
    }
  }
  return s;
}

/// Per-tile samples of the tracer over `view` (the image of `db`'s view,
/// in 8x8-pixel tiles): each tile's operation counts and the least CPU time
/// of `repeat` passes, after `warmup` passes that are not timed.
/// `counters(c)` writes the counts the tracer does not keep (the pager's)
/// into `c`, as running totals; `pixel(trace)` runs one pixel's `trace()`.
template <class View, class Counters, class Pixel>
std::vector<core::CostSample> sample_tiles(const View& view, const core::Database& db, int width, int height,
                                           int warmup, int repeat, Counters&& counters, Pixel&& pixel) {
  const core::Camera camera(core::render_view(db), width, height);
  const core::ShadingContext shading = core::make_shading_context(db);
  constexpr int kTile = 8;
  const int tx = (width + kTile - 1) / kTile, ty = (height + kTile - 1) / kTile;
  std::vector<core::CostSample> samples(std::size_t(tx) * ty);
  std::vector<double> best(samples.size(), 1e30);
  core::ShadingScratch scratch;
  auto counts = [&] {
    core::CostCounts c = core::cost_counts(scratch.stats.rays, scratch.traversal.stats);
    counters(c);
    return c;
  };
  for (int pass = 0; pass < warmup + repeat; ++pass)
    for (int j = 0; j < ty; ++j)
      for (int i = 0; i < tx; ++i) {
        const core::CostCounts before = counts();
        const double t0 = nodes::thread_cpu_seconds();
        for (int y = j * kTile; y < std::min(height, (j + 1) * kTile); ++y)
          for (int x = i * kTile; x < std::min(width, (i + 1) * kTile); ++x)
            pixel([&] { (void)core::render_pixel(view, shading, camera, x, y, 1, false, scratch); });
        const double dt = nodes::thread_cpu_seconds() - t0;
        if (pass < warmup) continue;
        const core::CostCounts after = counts();
        const std::size_t k = std::size_t(j) * tx + i;
        for (int f = 0; f < core::kCostFeatureCount; ++f)
          samples[k].counts[std::size_t(f)] = after[std::size_t(f)] - before[std::size_t(f)];
        best[k] = std::min(best[k], dt);
      }
  for (std::size_t k = 0; k < samples.size(); ++k) samples[k].seconds = best[k];
  return samples;
}

/// Per-tile samples of the sequential tracer over `db`.
std::vector<core::CostSample> tile_samples(const core::Database& db, const core::Grid& grid, int width, int height,
                                           int repeat) {
  return sample_tiles(
      core::DirectView(db, grid), db, width, height, 0, repeat, [](core::CostCounts&) {},
      [](auto&& trace) { trace(); });
}

/// Per-tile samples of the svm tracer on node 0 of a 1- and a 2-node
/// machine (the pager and PagedView of svm mode, every page cached after a
/// first pass that takes the faults; node 1 only serves page requests, so
/// node 0 computes alone and its tiles' CPU times hold no emulator cost).
std::vector<core::CostSample> pager_samples(const core::Database& db, const core::Grid& grid, int width, int height,
                                            int repeat) {
  const svm::PagedImage image = svm::build_paged_image(db, grid, 1024);
  std::vector<core::CostSample> out;
  for (std::uint32_t n : {1u, 2u}) {
    nodes::MachineParams mp;
    mp.nodes = n;
    mp.node_memory = std::size_t(2) * image.layout.bytes() + (std::size_t(16) << 20);
    mp.max_payload = sizeof(svm::PageReplyMsg) + image.layout.page_size;
    mp.timeout_s = 600;
    std::vector<core::CostSample> samples;
    nodes::Machine machine(mp);
    machine.run(
        [&](nodes::NodeContext& ctx) {
          svm::Pager pager(ctx, image.layout, ctx.id() == 0 && n > 1 ? image.layout.pages : 0);
          // The cache never fills here: keep the LRU order anyway, so that
          // the samples hold the LRU updates of a full cache.
          pager.keep_lru_order();
          for (std::uint32_t p = ctx.id(); p < image.layout.pages; p += n)
            std::memcpy(pager.home_frame(p), image.page(p).data(), image.layout.page_size);
          if (ctx.id() != 0) {
            while (true) {
              const nodes::Message m = ctx.receive(nodes::WaitKind::kIdle);
              if (m.type() == nodes::MessageType::kTest) return;
              pager.serve(m);
            }
          }
          auto pager_counts = [&](core::CostCounts& c) {
            const svm::PagerStats& p = pager.stats();
            c[std::size_t(core::CostFeature::kPageAccess)] = double(p.accesses);
            c[std::size_t(core::CostFeature::kLruUpdate)] = double(p.lru_updates());
            c[std::size_t(core::CostFeature::kPageFault)] = double(p.misses);
            c[std::size_t(core::CostFeature::kCachePageAccess)] = double(p.cache_page_accesses);
          };
          auto in_pixel = [&](auto&& trace) {
            pager.begin_pixel();
            trace();
            pager.end_pixel();
          };
          // Pass 0 takes the faults.
          samples = sample_tiles(svm::PagedView(pager, grid.info, db.materials), db, width, height, 1, repeat,
                                 pager_counts, in_pixel);
          for (nodes::NodeId other = 1; other < n; ++other)
            ctx.send(other, nodes::MessageType::kTest, std::uint32_t(0));
        },
        [](nodes::NodeContext&) {});
    out.insert(out.end(), samples.begin(), samples.end());
  }
  return out;
}

/// sum(model) / sum(measured) over `samples`, and the RMS relative error per sample.
std::pair<double, double> fit_quality(const core::CostModel& m, std::span<const core::CostSample> samples) {
  double model = 0, measured = 0, sq = 0;
  for (const core::CostSample& s : samples) {
    const double p = m.seconds(s.counts);
    model += p;
    measured += s.seconds;
    if (s.seconds > 0) sq += (p / s.seconds - 1) * (p / s.seconds - 1);
  }
  return {measured > 0 ? model / measured : 0.0, samples.empty() ? 0.0 : std::sqrt(sq / double(samples.size()))};
}

/// A fit of the unit costs on this host, with the samples it was made on.
struct HostFit {
  core::CostModel model;
  std::vector<core::CostSample> tiles, pager;
  std::vector<std::pair<std::string, std::vector<core::CostSample>>> per_scene;
};

/// The fit itself: samples the scenes, then fits the tracer's unit costs
/// on the tiles and the pager's on the svm tiles.
HostFit fit_on_host(const CostModelOptions& o) {
  HostFit f;
  std::vector<core::CostSample>& tiles = f.tiles;
  std::vector<core::CostSample>& pager = f.pager;
  std::vector<std::pair<std::string, std::vector<core::CostSample>>>& per_scene = f.per_scene;
  for (const std::string& text : o.scenes) {
    const core::SceneSource src = parse_scene(text);
    const core::Database db = core::make_database(core::load_scene(src));
    core::GridParams gp;
    gp.kind = grid_kind_for(o.grid);
    const core::Grid grid = core::build_grid(db, gp);
    if (!o.quiet) fmt::print(stderr, "{}: tiles...\n", text);
    std::vector<core::CostSample> t = tile_samples(db, grid, o.width, o.height, o.repeat);
    tiles.insert(tiles.end(), t.begin(), t.end());
    per_scene.emplace_back(text, std::move(t));
    if (o.pager) {
      if (!o.quiet) fmt::print(stderr, "{}: svm tiles...\n", text);
      const std::vector<core::CostSample> p = pager_samples(db, grid, o.width, o.height, o.repeat);
      pager.insert(pager.end(), p.begin(), p.end());
    }
  }
  std::array<bool, core::kCostFeatureCount> tracer{}, paging{};
  for (int k = 0; k < core::kCostFeatureCount; ++k) {
    const bool is_pager = k >= int(core::CostFeature::kPageAccess);
    tracer[std::size_t(k)] = !is_pager;
    // A fault's CPU time in an emulated run is mostly the emulator's
    // (thread wake-up, cold caches): its cost stays the modelled one. A
    // cached page's access costs this host no more than another access
    // (kPageAccess): it stays 0 unless a machine description prices it.
    paging[std::size_t(k)] = is_pager && k != int(core::CostFeature::kPageFault) &&
                             k != int(core::CostFeature::kCachePageAccess);
  }
  core::CostModel start;
  start.unit_s[std::size_t(core::CostFeature::kPageFault)] =
      core::default_cost_model().unit_s[std::size_t(core::CostFeature::kPageFault)];
  if (!o.fit.empty()) {
    start = core::default_cost_model();
    for (int k = 0; k < core::kCostFeatureCount; ++k) {
      const bool chosen = std::find(o.fit.begin(), o.fit.end(),
                                    core::cost_feature_name(core::CostFeature(k))) != o.fit.end();
      tracer[std::size_t(k)] = tracer[std::size_t(k)] && chosen;
      paging[std::size_t(k)] = paging[std::size_t(k)] && chosen;
    }
  }
  f.model = core::fit_cost_model(tiles, tracer, start);
  if (o.pager) f.model = core::fit_cost_model(pager, paging, f.model);
  return f;
}

}  // namespace

core::CostModel fit_cost_model_on_host() {
  CostModelOptions o;
  o.quiet = true;
  return fit_on_host(o).model;
}

void register_bench_cost_model_command(CLI::App& app) {
  CLI::App* bench = app.get_subcommand("bench");
  auto o = std::make_shared<CostModelOptions>();
  CLI::App* c = bench->add_subcommand(
      "cost-model", "Fit the model clock's unit costs (--clock model) on this machine and print them with the fit");
  c->add_option("--scenes", o->scenes, "Scenes to fit on: SCENE or SCENE@R (tessellated R)")
      ->delimiter(',')
      ->capture_default_str();
  c->add_option("--width", o->width, "Image width")->check(CLI::Range(8, 4096))->capture_default_str();
  c->add_option("--height", o->height, "Image height")->check(CLI::Range(8, 4096))->capture_default_str();
  c->add_option("--repeat", o->repeat, "Passes per tile (the least time counts)")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  c->add_flag("!--no-pager", o->pager, "Skip the svm pager's costs");
  add_grid_option(*c, o->grid);
  std::vector<std::string> names;
  for (int k = 0; k < core::kCostFeatureCount; ++k) names.push_back(core::cost_feature_name(core::CostFeature(k)));
  c->add_option("--fit", o->fit,
                "Fit only these unit costs (e.g. empty_jump); the others keep the built-in model's [default: all]")
      ->check(CLI::IsMember(names))
      ->delimiter(',');
  c->add_flag("--quiet,-q", o->quiet, "No progress lines on stderr");
  c->callback([o] {
    const HostFit f = fit_on_host(*o);
    const core::CostModel& m = f.model;
    const std::vector<core::CostSample>& pager = f.pager;
    const auto& per_scene = f.per_scene;
    const std::vector<core::CostSample>& tiles = f.tiles;

    fmt::print("unit costs (ns), fitted on {} tiles{}:\n", tiles.size(),
               o->pager ? fmt::format(" and {} svm tiles", pager.size()) : "");
    for (int k = 0; k < core::kCostFeatureCount; ++k)
      fmt::print("  {:<14} {:10.3f}\n", core::cost_feature_name(core::CostFeature(k)), 1e9 * m.unit_s[std::size_t(k)]);
    fmt::print("\n{:<12} {:>12} {:>12} {:>10} {:>14}\n", "scene", "measured_s", "model_s", "model/cpu",
               "rms_rel_err");
    for (const auto& [name, samples] : per_scene) {
      double measured = 0;
      for (const core::CostSample& s : samples) measured += s.seconds;
      const auto [ratio, rms] = fit_quality(m, samples);
      fmt::print("{:<12} {:12.4f} {:12.4f} {:10.3f} {:14.3f}\n", name, measured, ratio * measured, ratio, rms);
    }
    if (o->pager) {
      const auto [ratio, rms] = fit_quality(m, pager);
      fmt::print("{:<12} {:>12} {:>12} {:10.3f} {:14.3f}\n", "svm tiles", "", "", ratio, rms);
    }
    fmt::print("\nbuilt in now: {}\n", core::kCostModelSource);
  });
}

}  // namespace raynode::apps
