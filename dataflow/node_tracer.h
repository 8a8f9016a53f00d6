// A node's program in dataflow mode (dataflow.h has the whole protocol):
// what the node holds in its arena, the memory it needs besides its region
// database, and the tracer that runs on it. Internal to the dataflow
// library: render_dataflow (dataflow.cpp) fills NodeState before the run.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>

#include "core/camera.h"
#include "core/cost_model.h"
#include "core/database.h"
#include "core/grid.h"
#include "core/shade.h"
#include "dataflow/dataflow.h"
#include "dataflow/messages.h"
#include "dataflow/region.h"
#include "dataflow/send_queue.h"
#include "nodes/arena.h"
#include "nodes/machine.h"
#include "nodes/node.h"

namespace raynode::dataflow {

/// A node's own primary ray: pixel and sample (spp^2 = the AOV-only centre ray).
struct PrimarySample {
  std::uint32_t pixel;
  std::uint32_t sample;
};

/// The primary ray of a sample, exactly as core::render_pixel casts it
/// (sample spp^2: the AOV-only ray through the pixel centre).
/// The primary ray of a sample, exactly as core::render_pixel casts it.
core::Ray primary_ray(const core::Camera& camera, int spp, std::uint32_t pixel, std::uint32_t sample);

/// A received ray and its arrival time (virtual seconds).
struct Pending {
  RayMsg ray;
  double arrival;
};

/// Everything a node holds (arena arrays) plus O(1) metadata by value.
struct NodeState {
  NodeState(const core::Camera& c) : camera(c) {}
  nodes::Arena* arena = nullptr;
  /// The progress line's pixel counter (core::RenderParams::progress), or
  /// null: a meter for the user, outside the emulated machine.
  std::atomic<std::uint64_t>* progress = nullptr;
  core::TopGridInfo grid;
  core::Camera camera;
  core::Vec3 background;
  core::Bounds3 scene_box;
  CameraFrame frame;
  int spp = 1, max_depth = 5;
  float min_weight = 0;
  core::ShadowRays shadow_rays = core::ShadowRays::kFacing;
  nodes::ArenaArray<core::Primitive> primitives;
  nodes::ArenaArray<core::TriangleNormals> vertex_normals;
  nodes::ArenaArray<core::Material> materials;
  nodes::ArenaArray<std::uint32_t> cell_start;
  nodes::ArenaArray<std::uint32_t> cell_primitives;
  nodes::ArenaArray<std::uint8_t> empty_distance;
  nodes::ArenaArray<core::SubGrid> sub_grids;          ///< adaptive local grid only
  nodes::ArenaArray<std::uint32_t> cell_entries;       ///< adaptive local grid only
  nodes::ArenaArray<std::uint8_t> shared;
  nodes::ArenaArray<core::Light> lights;
  nodes::ArenaArray<KdNode> tree;
  nodes::ArenaArray<ScreenRect> rects;
  nodes::ArenaArray<PrimarySample> primaries;
  nodes::ArenaArray<RayMsg> stack;
  nodes::ArenaArray<Pending> inbox;  ///< received rays not yet traced (ring)
  SendQueue send_queue;  ///< rays waiting for room at their destination (send_queue.h)
  nodes::ArenaArray<Contribution> contributions;
  nodes::ArenaArray<FirstHitRecord> first_hits;
  core::ShadingScratch* scratch = nullptr;
  NodeFlowStats stats;
  core::CostModel cost_model;

  /// The model clock's work meter (NodeContext::set_work_meter): the
  /// tracer's operations, plus a traversal start (priced as a shadow ray)
  /// for each received ray, whose segment here continues a ray begun in
  /// another region.
  static double work_seconds(const void* self) {
    const NodeState& s = *static_cast<const NodeState*>(self);
    std::uint64_t continued = 0;
    for (std::uint64_t r : s.stats.rays_received) continued += r;
    return s.cost_model.seconds(s.scratch->stats.rays, s.scratch->traversal.stats) +
           s.cost_model.unit_s[std::size_t(core::CostFeature::kShadowRay)] * double(continued);
  }
  ~NodeState() {
    if (arena) arena->destroy(scratch);
  }
};

/// Incoming messages a node parks while a send to the host waits for room
/// (NodeContext::set_park_limit): the arena room node_budget reserves for
/// them. A node's only blocking sends go to the host, which never waits for
/// a node, so a node that stops parking cannot deadlock anyone.
constexpr std::size_t kParkLimit = 256;

/// Bytes a node needs besides its region database (checked before the run).
struct NodeBudget {
  std::size_t stack_slots, inbox_slots, contribution_slots, first_hit_slots;
  /// The sending queue's least size (one mailbox's worth); it also takes
  /// whatever the node's memory has left once everything else is loaded.
  std::size_t send_queue_slots;
  bool send_queue_fixed;  ///< send_queue_slots is the size asked for: the queue takes no more
  std::size_t parking;  ///< room kept free for parked messages (part of `fixed`)
  std::size_t fixed;  ///< mailbox, receive buffer, stack, queues, buffers, kd-tree, lights, scratch, parking room
};

/// The arena bytes a node needs besides its region database, for a machine
/// `m`, `lights` lights, rays up to level `max_depth`, `regions` regions and
/// a region tree of `tree_nodes` nodes; `send_queue_slots` as
/// DataflowParams::send_queue_slots (0: one mailbox's worth at least).
NodeBudget node_budget(const nodes::MachineParams& m, std::size_t lights, int max_depth, std::uint32_t regions,
                       std::size_t tree_nodes, std::size_t send_queue_slots = 0);

/// Runs node `ctx`'s side of the frame over its state `s` until the host
/// shuts the machine down. `want_first_hit`: report the first hit of each
/// pixel's centre ray (AOVs). Throws std::logic_error on a protocol fault.
void run_node_tracer(nodes::NodeContext& ctx, NodeState& s, bool want_first_hit);

}  // namespace raynode::dataflow
