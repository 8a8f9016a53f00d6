#include "control/replicated.h"

#include <fmt/core.h>

#include <algorithm>
#include <cstring>
#include <memory>
#include <stdexcept>

#include "core/camera.h"
#include "core/direct_view.h"
#include "core/shade.h"
#include "control/image_frame.h"
#include "control/pixel_record.h"

namespace raynode::control {

namespace {

/// Everything a node holds: the arrays in its arena, plus O(1) metadata
/// (grid description, camera, background, parameters) copied by value, so
/// the node thread reads nothing of the host's.
struct NodeState {
  NodeState(const core::TopGridInfo& g, const core::Camera& c, const core::Vec3& bg, const core::RenderParams& p,
            const Rect& submap)
      : grid(g), camera(c), background(bg), render(p), submap(submap) {}
  core::TopGridInfo grid;
  core::Camera camera;
  core::Vec3 background;
  core::RenderParams render;
  Rect submap;
  ArenaArray<core::Primitive> primitives;
  ArenaArray<core::TriangleNormals> vertex_normals;
  ArenaArray<core::Material> materials;
  ArenaArray<std::uint32_t> cell_start;
  ArenaArray<std::uint32_t> cell_primitives;
  ArenaArray<std::uint8_t> empty_distance;
  ArenaArray<core::SubGrid> sub_grids;         ///< adaptive grid only
  ArenaArray<std::uint32_t> cell_entries;      ///< adaptive grid only
  ArenaArray<core::Light> lights;
  PixelBatch batch;  ///< outgoing pixel blocks (one message's payload)
  core::ShadingScratch* scratch = nullptr;
  Arena* arena = nullptr;
  core::RenderStats stats;
  WorkStats work;
  core::CostModel cost_model;

  /// The model clock's work meter (NodeContext::set_work_meter).
  static double work_seconds(const void* self) {
    const NodeState& s = *static_cast<const NodeState*>(self);
    return s.cost_model.seconds(s.scratch->stats.rays, s.scratch->traversal.stats);
  }

  ~NodeState() {
    if (arena) arena->destroy(scratch);
  }
};

}  // namespace

std::size_t replicated_bytes_per_node(const core::Database& db, const core::Grid& grid) {
  return core::DatabaseArrays::of(db, grid).bytes() + db.lights.size() * sizeof(core::Light);
}

ReplicatedResult render_replicated(const core::Database& db, const core::Grid& grid, const ReplicatedParams& params) {
  const core::RenderParams& rp = params.render;
  const ImageFrame frame = image_frame(db, rp, params.item_w, params.item_h);
  const PixelLayout layout(rp);

  MachineParams mp = params.machine;
  mp.max_payload = std::max(mp.max_payload, pixels_payload_bytes(params.item_w, params.item_h, layout.channels));
  Machine machine(mp);  // validates the node count
  const MachineParams& m = machine.params();

  // Fail early, with the sizes, when a copy cannot fit beside the mailbox.
  const core::DatabaseArrays host_arrays = core::DatabaseArrays::of(db, grid);
  const std::size_t copy_bytes = replicated_bytes_per_node(db, grid);
  const SubmapPlan plan = plan_submaps(db, grid, frame.camera, rp, m.nodes, params.submaps, m.cost_model);
  const std::vector<Rect>& submaps = plan.rects;
  const std::size_t fixed = Mailbox::bytes_for(m.mailbox_capacity, m.max_payload) + m.max_payload + PixelBatch::bytes(m.max_payload) +
                            sizeof(core::ShadingScratch) + work_farm_bytes(resolved_work_grant(m), submaps, params.item_w, params.item_h);
  if (copy_bytes + fixed > m.node_memory)
    throw DoesNotFit(fmt::format("replicated mode: the database needs {} per node ({} B, plus {} for the mailbox "
                                 "and buffers), --node-memory is {} ({} B)",
                                 format_bytes(copy_bytes), copy_bytes, format_bytes(fixed),
                                 format_bytes(m.node_memory), m.node_memory),
                     copy_bytes + fixed, m.node_memory);

  ReplicatedResult out;
  out.database_bytes = copy_bytes;
  out.submaps = plan;
  core::Image* const extra[] = {&out.node};
  size_images(out.render, rp, frame, std::span<core::Image* const>(extra, params.node_aov ? 1 : 0));

  std::vector<std::unique_ptr<NodeState>> states(m.nodes);

  // The host loads each node's memory: the load phase, outside virtual time.
  auto setup = [&](NodeContext& ctx) {
    Arena& a = ctx.arena();
    auto s = std::make_unique<NodeState>(grid.info, frame.camera, db.background, rp, submaps[ctx.id()]);
    s->arena = &a;
    s->primitives = copy_to_arena(a, host_arrays.primitives, "the database copy (primitives)");
    s->vertex_normals = copy_to_arena(a, host_arrays.vertex_normals, "the database copy (vertex normals)");
    s->materials = copy_to_arena(a, host_arrays.materials, "the database copy (materials)");
    s->cell_start = copy_to_arena(a, host_arrays.cell_start, "the database copy (grid cells)");
    s->cell_primitives = copy_to_arena(a, host_arrays.cell_primitives, "the database copy (cell lists)");
    s->empty_distance = copy_to_arena(a, host_arrays.empty_distance, "the database copy (empty-space distances)");
    s->sub_grids = copy_to_arena(a, host_arrays.sub_grids, "the database copy (sub-grids)");
    s->cell_entries = copy_to_arena(a, host_arrays.cell_entries, "the database copy (sub-grid cell entries)");
    s->lights = copy_to_arena(a, std::span<const core::Light>(db.lights), "the lights");
    s->batch = PixelBatch(a, m.max_payload);
    s->scratch = a.create<core::ShadingScratch>("its tracing scratch");
    s->cost_model = m.cost_model;
    states[ctx.id()] = std::move(s);
  };

  auto node_main = [&](NodeContext& ctx) {
    NodeState& s = *states[ctx.id()];
    core::DatabaseArrays mine{s.primitives.span(), s.vertex_normals.span(), s.materials.span(),
                              s.cell_start.span(), s.cell_primitives.span(), s.empty_distance.span(), s.grid};
    mine.sub_grids = s.sub_grids.span();
    mine.cell_entries = s.cell_entries.span();
    const core::ShadingContext shading = core::make_shading_context(
        std::span<const core::Light>(s.lights.span()), s.background, s.render.max_depth, s.render.min_weight,
        s.render.shadow_rays);
    ctx.set_work_meter(&NodeState::work_seconds, &s);
    const PixelJob job{shading, s.camera, s.render.spp, s.render.any_aov(), layout, *s.scratch, s.batch};
    s.work = render_items(ctx, s.submap, params.item_w, params.item_h, core::DirectView(mine), job);
    s.stats = s.scratch->stats;
    s.stats.traversal = s.scratch->traversal.stats;
  };

  auto host_main = [&](NodeContext& host) { assemble_pixels(host, layout, out.render, out.node, rp.progress); };

  out.tracing.resize(m.nodes);
  out.work.resize(m.nodes);
  out.run = machine.run(node_main, host_main, setup, [&](NodeContext& ctx) {
    // Keep the counters, free the arena's contents.
    if (states[ctx.id()]) {
      out.tracing[ctx.id()] = states[ctx.id()]->stats;
      out.work[ctx.id()] = states[ctx.id()]->work;
    }
    states[ctx.id()].reset();
  });
  machine.gather(out.tracing);  // another process's nodes' counters (a transport), to the host's
  machine.gather(out.work);
  for (const core::RenderStats& s : out.tracing) out.render.stats += s;
  return out;
}

}  // namespace raynode::control
