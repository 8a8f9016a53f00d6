#include "dataflow/dataflow.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <stdexcept>

#include "core/camera.h"
#include "dataflow/host.h"
#include "dataflow/node_tracer.h"
#include "dataflow/region_view.h"

namespace raynode::dataflow {

using nodes::Arena;
using nodes::ArenaArray;
using nodes::NodeContext;

namespace {

/// Node memory a dataflow node keeps free besides its parking room when
/// the sending queue takes the rest (allocation slack).
constexpr std::size_t kSendQueueSlack = 64 * 1024;

/// "a 12x9x20 grid with 3456 references", or for an adaptive local grid
/// "an adaptive grid (12x9x20 top grid, 7 sub-grids, 4321 leaf cells) with 5678 references".
std::string grid_phrase(const RegionReport& r) {
  if (r.grid_kind == core::GridKind::kUniform)
    return fmt::format("a {}x{}x{} grid with {} references", r.grid_res[0], r.grid_res[1], r.grid_res[2],
                       r.grid_references);
  return fmt::format("an adaptive grid ({}x{}x{} top grid, {} sub-grids, {} leaf cells) with {} references",
                     r.grid_res[0], r.grid_res[1], r.grid_res[2], r.grid_sub_grids, r.grid_leaf_cells,
                     r.grid_references);
}

/// The regions of `n` nodes cut from `cost` over the scene's screen
/// `extent`. A refined estimate's cuts cover only where the work is: the
/// outer regions' finite rectangles reach on to the extent, which their
/// local grids must cover.
Partition partition_scene(const CameraFrame& frame, const CostGrid& cost, std::uint32_t n, const ScreenRect& extent) {
  Partition partition = make_partition(frame, cost, n);
  for (std::uint32_t r = 0; r < partition.region_count(); ++r) {
    const ScreenRect& own = partition.rects[r];
    ScreenRect& f = partition.finite[r];
    if (std::isinf(own.x0)) f.x0 = std::min(f.x0, extent.x0);
    if (std::isinf(own.y0)) f.y0 = std::min(f.y0, extent.y0);
    if (std::isinf(own.x1)) f.x1 = std::max(f.x1, extent.x1);
    if (std::isinf(own.y1)) f.y1 = std::max(f.y1, extent.y1);
  }
  partition.extent = extent;
  return partition;
}

/// Each node's own primary rays: the `samples` samples of every pixel, each
/// given to the region where it enters `scene_box` (a ray that misses it to
/// node pixel mod n).
std::vector<std::vector<PrimarySample>> primaries_by_region(const core::Camera& camera, int spp,
                                                            std::uint32_t samples, const core::Bounds3& scene_box,
                                                            const CameraFrame& frame, const RegionMap& map,
                                                            std::uint32_t n) {
  std::vector<std::vector<PrimarySample>> primaries(n);
  const std::uint32_t pixels = std::uint32_t(camera.width()) * std::uint32_t(camera.height());
  for (std::uint32_t pixel = 0; pixel < pixels; ++pixel)
    for (std::uint32_t k = 0; k < samples; ++k) {
      const core::Ray ray = primary_ray(camera, spp, pixel, k);
      const core::Vec3 inv{1.0f / ray.direction.x, 1.0f / ray.direction.y, 1.0f / ray.direction.z};
      float ta, tb;
      const std::uint32_t owner = core::intersect_bounds(scene_box, ray, inv, ta, tb)
                                      ? map.region_at(ScreenRay::of(frame, ray.origin, ray.direction), ta)
                                      : pixel % n;
      primaries[owner].push_back(PrimarySample{pixel, k});
    }
  return primaries;
}

/// Region r as built, before the run.
RegionReport report_region(std::uint32_t r, const Partition& partition, const RegionDatabase& rd,
                           const CostGrid& estimate) {
  RegionReport rr;
  rr.rect = partition.rects[r];
  rr.finite = partition.finite[r];
  rr.node = r;
  rr.primitives = rd.db.primitives.size();
  for (std::uint8_t s : rd.shared) rr.shared_primitives += s;
  rr.grid_kind = rd.grid.kind();
  rr.grid_references = rd.grid.references();
  for (int a = 0; a < 3; ++a) rr.grid_res[a] = rd.grid.info.res[a];
  rr.grid_sub_grids = rd.grid.sub_grid_count();
  rr.grid_leaf_cells = rd.grid.leaf_cells();
  rr.grid_bytes = rd.grid.bytes();
  rr.bytes = rd.bytes();
  rr.estimated_cost = cost_in(estimate, partition.finite[r]);
  return rr;
}

/// Throws nodes::DoesNotFit, with the sizes, when region r (its database,
/// `primaries` own primary rays and the node's fixed needs) exceeds the
/// node's memory.
void check_fits(std::uint32_t r, const RegionReport& rr, std::size_t primaries, const NodeBudget& budget,
                const nodes::MachineParams& m) {
  const std::size_t need = rr.bytes + primaries * sizeof(PrimarySample) + budget.fixed;
  if (need <= m.node_memory) return;
  throw nodes::DoesNotFit(
      fmt::format("dataflow mode: region {} needs {} ({} B: {} primitives, {} ({}), {} own primary rays, {} for "
                  "the mailbox and buffers), --node-memory is {} ({} B)",
                  r, nodes::format_bytes(need), need, rr.primitives, grid_phrase(rr),
                  nodes::format_bytes(rr.grid_bytes), primaries, nodes::format_bytes(budget.fixed),
                  nodes::format_bytes(m.node_memory), m.node_memory),
      need, m.node_memory);
}

/// The host's frame buffer and the AOVs asked for, w x h: depth +inf and
/// primitive and region -1 where nothing is hit.
void size_frame(DataflowResult& out, const core::RenderParams& rp, bool region_aov, int w, int h) {
  out.render.color = core::Image(w, h, 3);
  if (rp.depth_aov) {
    out.render.depth = core::Image(w, h, 1);
    std::fill(out.render.depth.pixels.begin(), out.render.depth.pixels.end(), core::kInfinity);
  }
  if (rp.normal_aov) out.render.normal = core::Image(w, h, 3);
  if (rp.primitive_aov) {
    out.render.primitive = core::Image(w, h, 1);
    std::fill(out.render.primitive.pixels.begin(), out.render.primitive.pixels.end(), -1.0f);
  }
  if (region_aov) {
    out.region = core::Image(w, h, 1);
    std::fill(out.region.pixels.begin(), out.region.pixels.end(), -1.0f);
  }
}

/// What every node gets besides its region: the frame's O(1) parameters and
/// the tables all nodes share.
struct SharedInputs {
  const core::Database& db;
  const core::Camera& camera;
  const CameraFrame& frame;
  const core::Bounds3& scene_box;
  const core::RenderParams& render;
  const Partition& partition;
  const NodeBudget& budget;
  const core::CostModel& cost_model;
};

/// A node's state in its arena `a`: its region `rd`, its own primary rays,
/// the shared tables and its buffers (node_budget's sizes).
std::unique_ptr<NodeState> make_node_state(Arena& a, const RegionDatabase& rd,
                                           std::span<const PrimarySample> primaries, const SharedInputs& in) {
  auto s = std::make_unique<NodeState>(in.camera);
  s->arena = &a;
  s->progress = in.render.progress;
  s->grid = rd.grid.info;
  s->background = in.db.background;
  s->scene_box = in.scene_box;
  s->frame = in.frame;
  s->spp = in.render.spp;
  s->max_depth = in.render.max_depth;
  s->min_weight = in.render.min_weight;
  s->shadow_rays = in.render.shadow_rays;
  s->primitives = nodes::copy_to_arena(a, std::span<const core::Primitive>(rd.db.primitives), "the region's primitives");
  s->vertex_normals =
      nodes::copy_to_arena(a, std::span<const core::TriangleNormals>(rd.db.vertex_normals), "the region's vertex normals");
  s->materials = nodes::copy_to_arena(a, std::span<const core::Material>(rd.db.materials), "the materials");
  s->cell_start = nodes::copy_to_arena(a, std::span<const std::uint32_t>(rd.grid.cell_start), "the region's grid cells");
  s->cell_primitives =
      nodes::copy_to_arena(a, std::span<const std::uint32_t>(rd.grid.cell_primitives), "the region's cell lists");
  s->empty_distance = nodes::copy_to_arena(a, std::span<const std::uint8_t>(rd.grid.empty_distance),
                                           "the region's empty-space distances");
  if (rd.grid.kind() == core::GridKind::kAdaptive) {  // a uniform grid has none (and allocates nothing more)
    s->sub_grids = nodes::copy_to_arena(a, std::span<const core::SubGrid>(rd.grid.sub_grids), "the region's sub-grids");
    s->cell_entries = nodes::copy_to_arena(a, std::span<const std::uint32_t>(rd.grid.cell_entries),
                                           "the region's sub-grid cell entries");
  }
  s->shared = nodes::copy_to_arena(a, std::span<const std::uint8_t>(rd.shared), "the shared-primitive flags");
  s->lights = nodes::copy_to_arena(a, std::span<const core::Light>(in.db.lights), "the lights");
  s->tree = nodes::copy_to_arena(a, std::span<const KdNode>(in.partition.tree), "the region tree");
  s->rects = nodes::copy_to_arena(a, std::span<const ScreenRect>(in.partition.rects), "the region rectangles");
  s->primaries = nodes::copy_to_arena(a, primaries, "its primary rays");
  s->stack = ArenaArray<RayMsg>(a, in.budget.stack_slots, "its ray stack");
  s->inbox = ArenaArray<Pending>(a, in.budget.inbox_slots, "its inbox");
  s->contributions = ArenaArray<Contribution>(a, in.budget.contribution_slots, "its contribution buffer");
  s->first_hits = ArenaArray<FirstHitRecord>(a, in.budget.first_hit_slots, "its first-hit buffer");
  s->scratch = a.create<core::ShadingScratch>("its tracing scratch");
  // The sending queue takes the memory left, as the paper's message queues
  // did ("Deadlock"), but for the parking room and some slack.
  const std::uint32_t n = std::uint32_t(in.partition.rects.size());
  const std::size_t keep = in.budget.parking + kSendQueueSlack + SendQueue::destination_bytes(n);
  const std::size_t left = a.available() > keep ? (a.available() - keep) / SendQueue::kSlotBytes : 0;
  s->send_queue = SendQueue(a, in.budget.send_queue_fixed ? in.budget.send_queue_slots : std::max(in.budget.send_queue_slots, left), n);
  s->cost_model = in.cost_model;
  return s;
}

/// The machine dataflow runs on: `machine` with room for a ray message in
/// every payload, the default mailbox capacity, and rays served when a core
/// is free rather than waited for (machine.h).
nodes::MachineParams dataflow_machine(nodes::MachineParams mp) {
  mp.max_payload = std::max<std::uint32_t>(mp.max_payload, 256);
  if (mp.mailbox_capacity == 0) mp.mailbox_capacity = kDefaultQueueCapacity;
  if (!mp.scheduled_mail) mp.scheduled_mail = true;
  return mp;
}

}  // namespace

DataflowResult render_dataflow(const core::Database& db, const core::Grid& grid, const DataflowParams& params) {
  const core::RenderParams& rp = params.render;
  if (rp.spp < 1) throw std::invalid_argument("spp must be >= 1");
  if (rp.max_depth < 1 || rp.max_depth > 255) throw std::invalid_argument("max depth must be 1..255");
  if (params.subsample < 1)
    throw std::invalid_argument(fmt::format("--subsample must be >= 1, got {}", params.subsample));
  const core::View cam_view = core::render_view(db);
  const int w = rp.width > 0 ? rp.width : cam_view.width;
  const int h = rp.height > 0 ? rp.height : cam_view.height;
  const core::Camera camera(cam_view, w, h);
  const CameraFrame frame = CameraFrame::of(cam_view);
  nodes::Machine machine(dataflow_machine(params.machine));  // validates the node count
  const nodes::MachineParams& m = machine.params();
  const std::uint32_t n = m.nodes;

  DataflowResult out;
  out.partition = params.partition;

  // 1. Load estimate (host, before the run).
  const ScreenRect extent = screen_extent(frame, db.bounds);
  EstimateParams ep;
  ep.subsample = params.subsample;
  ep.resolution = params.estimate_resolution;
  ep.spp = 1;
  ep.max_depth = rp.max_depth;
  ep.min_weight = rp.min_weight;
  ep.shadow_rays = rp.shadow_rays;
  ep.regions = n;
  out.estimate = estimate_load(db, grid, camera, frame, extent, ep);
  out.extent = extent;

  // 2. Partition and the regions' databases.
  const auto t0 = std::chrono::steady_clock::now();
  const Partition partition = partition_scene(
      frame,
      params.partition == PartitionKind::kEqual ? uniform_cost(extent, params.estimate_resolution) : out.estimate.cost,
      n, extent);
  const std::vector<RegionDatabase> regions = make_region_databases(db, partition, params.grid);

  // 3. Own primary rays, by the region where they enter the scene.
  // The whole scene's box (an adaptive top grid may cover less: core/grid.h).
  const core::Bounds3 scene_box = core::grid_bounds(db);
  const bool want_first = rp.any_aov() || params.region_aov;
  const std::uint32_t samples = std::uint32_t(rp.spp * rp.spp) + ((want_first && rp.spp % 2 == 0) ? 1u : 0u);
  const std::vector<std::vector<PrimarySample>> primaries =
      primaries_by_region(camera, rp.spp, samples, scene_box, frame, partition.map(), n);

  // Fail early, with the sizes, when a region does not fit its node.
  const NodeBudget budget = node_budget(m, db.lights.size(), rp.max_depth, n, partition.tree.size(), params.send_queue_slots);
  for (std::uint32_t r = 0; r < n; ++r) {
    out.regions.push_back(report_region(r, partition, regions[r], out.estimate.cost));
    check_fits(r, out.regions[r], primaries[r].size(), budget, m);
  }
  out.setup_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  // 4. The run: nodes trace (node_tracer.h), the host spills, sums and ends the frame (host.h).
  size_frame(out, rp, params.region_aov, w, h);
  std::vector<double> sums(std::size_t(w) * h * 3, 0.0);
  const SharedInputs shared{db, camera, frame, scene_box, rp, partition, budget, m.cost_model};
  std::vector<std::unique_ptr<NodeState>> states(n);
  auto setup = [&](NodeContext& ctx) {
    states[ctx.id()] = make_node_state(ctx.arena(), regions[ctx.id()], primaries[ctx.id()], shared);
  };
  auto node_main = [&](NodeContext& ctx) {
    ctx.set_work_meter(&NodeState::work_seconds, states[ctx.id()].get());
    ctx.set_park_limit(std::min<std::size_t>(m.mailbox_capacity, kParkLimit));
    run_node_tracer(ctx, *states[ctx.id()], want_first);
  };
  auto host_main = [&](NodeContext& host) {
    run_dataflow_host(host, n, HostFrame{w, h, &sums, &out.render, &out.region, &out.host});
  };
  out.per_node.resize(n);
  out.run = machine.run(node_main, host_main, setup, [&](NodeContext& ctx) {
    if (states[ctx.id()]) out.per_node[ctx.id()] = states[ctx.id()]->stats;
    states[ctx.id()].reset();
  });
  machine.gather(out.per_node);  // another process's nodes' counters (a transport), to the host's

  const float inv = 1.0f / float(rp.spp * rp.spp);
  for (std::size_t i = 0; i < std::size_t(w) * h; ++i)
    for (int c = 0; c < 3; ++c) out.render.color.pixels[i * 3 + c] = float(sums[i * 3 + c]) * inv;
  for (const NodeFlowStats& s : out.per_node) out.render.stats += s.tracing;
  return out;
}

}  // namespace raynode::dataflow
