#include "dataflow/dataflow.h"

#include <fmt/core.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <deque>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <thread>

#include "core/camera.h"
#include "core/direct_view.h"
#include "core/shade.h"
#include "core/traverse.h"
#include "dataflow/region_view.h"
#include "nodes/mailbox.h"

namespace raynode::dataflow {

using nodes::Arena;
using nodes::ArenaArray;
using nodes::Message;
using nodes::MessageType;
using nodes::NodeContext;
using nodes::NodeId;

const char* ray_kind_name(RayKind kind) {
  switch (kind) {
    case RayKind::kPrimary: return "primary";
    case RayKind::kShadow: return "shadow";
    case RayKind::kReflected: return "reflected";
    case RayKind::kRefracted: return "refracted";
  }
  return "?";
}

PartitionKind parse_partition(const std::string& name) {
  if (name == "balanced") return PartitionKind::kBalanced;
  if (name == "equal") return PartitionKind::kEqual;
  throw std::invalid_argument("unknown partition '" + name + "' (expected balanced or equal)");
}

const char* partition_name(PartitionKind kind) { return kind == PartitionKind::kEqual ? "equal" : "balanced"; }

namespace {

/// A node's own primary ray: pixel and sample (spp^2 = the AOV-only centre ray).
struct PrimarySample {
  std::uint32_t pixel;
  std::uint32_t sample;
};

/// The lower end of a region's query: a little before t_enter, so that a hit
/// exactly on the region boundary is not lost to rounding (a hit before
/// t_enter would have ended the ray in the previous region).
inline float query_start(float t_enter) { return std::max(0.0f, t_enter - 1e-5f * t_enter); }

/// The primary ray of a sample, exactly as core::render_pixel casts it.
core::Ray primary_ray(const core::Camera& camera, int spp, std::uint32_t pixel, std::uint32_t sample) {
  const int x = int(pixel % std::uint32_t(camera.width())), y = int(pixel / std::uint32_t(camera.width()));
  if (sample == std::uint32_t(spp * spp)) return camera.ray_through(float(x) + 0.5f, float(y) + 0.5f);
  const float n = float(spp);
  const int i = int(sample % std::uint32_t(spp)), j = int(sample / std::uint32_t(spp));
  return camera.ray_through(float(x) + (float(i) + 0.5f) / n, float(y) + (float(j) + 0.5f) / n);
}

/// A received ray and its arrival time (virtual seconds).
struct Pending {
  RayMsg ray;
  double arrival;
};

/// Everything a node holds (arena arrays) plus O(1) metadata by value.
struct NodeState {
  NodeState(const core::Camera& c) : camera(c) {}
  Arena* arena = nullptr;
  /// The progress line's pixel counter (core::RenderParams::progress), or
  /// null: a meter for the user, outside the emulated machine.
  std::atomic<std::uint64_t>* progress = nullptr;
  core::GridInfo grid;
  core::Camera camera;
  core::Vec3 background;
  core::Bounds3 scene_box;
  CameraFrame frame;
  int spp = 1, max_depth = 5;
  float min_weight = 0;
  ArenaArray<core::Primitive> primitives;
  ArenaArray<core::TriangleNormals> vertex_normals;
  ArenaArray<core::Material> materials;
  ArenaArray<std::uint32_t> cell_start;
  ArenaArray<std::uint32_t> cell_primitives;
  ArenaArray<std::uint8_t> empty_distance;
  ArenaArray<core::SubGrid> sub_grids;          ///< adaptive local grid only
  ArenaArray<std::uint32_t> cell_entries;       ///< adaptive local grid only
  ArenaArray<std::uint64_t> top_sub_grid_bits;  ///< adaptive local grid only
  ArenaArray<std::uint8_t> shared;
  ArenaArray<core::Light> lights;
  ArenaArray<KdNode> tree;
  ArenaArray<ScreenRect> rects;
  ArenaArray<PrimarySample> primaries;
  ArenaArray<RayMsg> stack;
  ArenaArray<Pending> inbox;  ///< received rays not yet traced (ring)
  ArenaArray<Contribution> contributions;
  ArenaArray<FirstHitRecord> first_hits;
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
  std::size_t fixed;  ///< mailbox, receive buffer, stack, buffers, kd-tree, lights, scratch, parking room
};

NodeBudget node_budget(const nodes::MachineParams& m, std::size_t lights, int max_depth, std::uint32_t regions,
                       std::size_t tree_nodes) {
  NodeBudget b;
  b.stack_slots = 2 + (lights + 2) * std::size_t(max_depth + 1);
  b.inbox_slots = std::max<std::size_t>(1, 4 * std::size_t(m.mailbox_capacity));
  b.contribution_slots = (m.max_payload - sizeof(ContributionHeader)) / sizeof(Contribution);
  b.first_hit_slots = (m.max_payload - sizeof(ContributionHeader)) / sizeof(FirstHitRecord);
  b.fixed = nodes::Mailbox::bytes_for(m.mailbox_capacity, m.max_payload) + m.max_payload +
            b.stack_slots * sizeof(RayMsg) + b.inbox_slots * sizeof(Pending) +
            b.contribution_slots * sizeof(Contribution) + b.first_hit_slots * sizeof(FirstHitRecord) +
            tree_nodes * sizeof(KdNode) +
            std::size_t(regions) * sizeof(ScreenRect) + lights * sizeof(core::Light) + sizeof(core::ShadingScratch) +
            // room for messages parked while a send to the host waits
            // (node.h; bounded by set_park_limit, kParkLimit)
            std::min<std::size_t>(m.mailbox_capacity, kParkLimit) * (m.max_payload + 96);
  return b;
}

/// A node's side of the frame.
class NodeTracer {
 public:
  /// `want_first_hit`: report the first hit of each pixel's centre ray (AOVs).
  NodeTracer(NodeContext& ctx, NodeState& s, bool want_first_hit)
      : want_first_hit_(want_first_hit),
        ctx_(ctx),
        s_(s),
        me_(ctx.id()),
        view_(arrays_of(s), s.shared.data(), &s.stats.shared_tests),
        map_{s.frame, s.tree.span(), s.rects.span()},
        shading_(core::make_shading_context(std::span<const core::Light>(s.lights.span()), s.background, s.max_depth,
                                            s.min_weight)),
        st_(s.scratch->stats) {}

  void run() {
    ctx_.mark_work_done();
    std::size_t next_primary = 0;
    bool worked = false;
    for (;;) {
      // The receiving queue: move mail into the inbox while it has room
      // (this needs no run permit, so a waiting node keeps taking mail).
      // poll() does not move the clock: a ray is traced once the node's clock
      // has reached its arrival (own primary rays fill the gap).
      Message m;
      while (inbox_size_ < s_.inbox.size() && ctx_.has_mail() && ctx_.poll(m))
        if (handle(m)) return finish_run();
      const bool local = stack_size_ > 0;
      if (local || inbox_size_ > 0 || next_primary < s_.primaries.size()) {
        // A run permit to compute; the scheduler's yield check (an O(nodes)
        // scan under a lock) once per kYieldEvery rays, not per ray segment.
        if (!ctx_.try_run() || (++units_ % kYieldEvery == 0 && !ctx_.yield_point())) {
          wait_for_permit();
          continue;
        }
        // A ray's local descendants first, then received rays that have
        // arrived, then own primary rays; with nothing else to do, the node
        // waits (in virtual time) for the next received ray.
        if (local) {
          const RayMsg r = s_.stack[--stack_size_];
          process(r);
        } else {
          bool ready = inbox_size_ > 0 && s_.inbox[inbox_head_].arrival <= clock_;
          // Reading the clock is a system call: refresh it once per kClockEvery own rays.
          if (inbox_size_ > 0 && !ready && (next_primary >= s_.primaries.size() || ++stale_ % kClockEvery == 0))
            ready = s_.inbox[inbox_head_].arrival <= (clock_ = ctx_.now());
          if (ready || (inbox_size_ > 0 && next_primary >= s_.primaries.size())) {
            const Pending p = s_.inbox[inbox_head_];
            inbox_head_ = (inbox_head_ + 1) % s_.inbox.size();
            --inbox_size_;
            if (!ready) ctx_.advance_to(p.arrival, nodes::WaitKind::kIdle);
            process(p.ray);
          } else {
            start_primary(s_.primaries[next_primary++]);
          }
        }
        worked = true;
        continue;
      }
      // Passive: flush, record the end of this work, answer a probe, wait.
      flush();
      if (worked) {
        ctx_.mark_work_done();
        worked = false;
      }
      if (probe_pending_) {
        probe_pending_ = false;
        ++s_.stats.waves_answered;
        ctx_.send(nodes::kHost, MessageType::kToken,
                  TokenMsg{probe_wave_, 0, s_.stats.work_sent, s_.stats.work_received});
      }
      if (handle(ctx_.receive(nodes::WaitKind::kIdle))) return finish_run();
    }
  }

 private:
  /// The node's region arrays as the view reads them (sub-grid tables empty for a uniform local grid).
  static core::DatabaseArrays arrays_of(const NodeState& s) {
    core::DatabaseArrays a{s.primitives.span(), s.vertex_normals.span(), s.materials.span(),
                           s.cell_start.span(), s.cell_primitives.span(), s.empty_distance.span(), s.grid};
    a.sub_grids = s.sub_grids.span();
    a.cell_entries = s.cell_entries.span();
    a.top_sub_grid_bits = s.top_sub_grid_bits.span();
    return a;
  }

  void finish_run() {
    s_.stats.tracing = st_;
    s_.stats.tracing.traversal = s_.scratch->traversal.stats;
  }

  /// Waits for the run permit. Mail ends a wait too, so with a full inbox
  /// the node naps instead of spinning. The CPU time of the wait is the
  /// emulator's, not the node's: it is dropped from the clock.
  void wait_for_permit() {
    if (ctx_.has_mail()) std::this_thread::sleep_for(std::chrono::microseconds(20));
    else ctx_.wait_for_mail(0);
    ctx_.reset_cpu_mark();
  }

  /// Returns true on shutdown.
  bool handle(const Message& m) {
    switch (m.type()) {
      case MessageType::kRay: {
        RayMsg r = m.as<RayMsg>();
        if (r.region != me_)
          throw std::logic_error(fmt::format("node {}: received a ray for region {}", me_, r.region));
        ++s_.stats.work_received;
        ++s_.stats.rays_received[std::size_t(r.kind)];
        if (inbox_size_ >= s_.inbox.size())
          throw std::logic_error(fmt::format("node {}: inbox overflow ({} rays)", me_, s_.inbox.size()));
        s_.inbox[(inbox_head_ + inbox_size_) % s_.inbox.size()] = Pending{r, m.header.arrival_time};
        ++inbox_size_;
        return false;
      }
      case MessageType::kToken:
        probe_pending_ = true;
        probe_wave_ = m.as<TokenMsg>().wave;
        return false;
      case MessageType::kShutdown:
        if (stack_size_ > 0 || inbox_size_ > 0)
          throw std::logic_error(fmt::format("node {}: shut down with rays pending", me_));
        return true;
      default:
        throw std::logic_error(fmt::format("node {}: unexpected {} message from {}", me_,
                                           nodes::message_type_name(m.type()), nodes::node_name(m.source())));
    }
  }

  void push(const RayMsg& m) {
    if (stack_size_ >= s_.stack.size())
      throw std::logic_error(fmt::format("node {}: local ray stack overflow ({} rays)", me_, s_.stack.size()));
    s_.stack[stack_size_++] = m;
  }

  void start_primary(const PrimarySample& p) {
    const core::Ray ray = primary_ray(s_.camera, s_.spp, p.pixel, p.sample);
    ++st_.rays.primary;
    ++s_.stats.primaries;
    if (p.sample == 0 && s_.progress) s_.progress->fetch_add(1, std::memory_order_relaxed);  // one per pixel
    std::uint8_t flags = 0;
    const int n2 = s_.spp * s_.spp;
    if (p.sample == std::uint32_t(n2)) flags = kRayFirstHit | kRayProbeOnly;
    else if (want_first_hit_ && (s_.spp % 2) == 1 && p.sample == std::uint32_t((s_.spp / 2) * s_.spp + s_.spp / 2))
      flags = kRayFirstHit;
    start_ray(ray, RayKind::kPrimary, p.pixel, 1, 1.0f, core::Vec3{}, flags);
  }

  /// A new ray from `ray.origin`: clipped to the scene box, then traced here
  /// or sent to the region where it enters the scene.
  void start_ray(const core::Ray& ray, RayKind kind, std::uint32_t pixel, int depth, float weight,
                 const core::Vec3& color, std::uint8_t flags) {
    RayMsg m;
    m.origin[0] = ray.origin.x, m.origin[1] = ray.origin.y, m.origin[2] = ray.origin.z;
    m.direction[0] = ray.direction.x, m.direction[1] = ray.direction.y, m.direction[2] = ray.direction.z;
    m.weight = weight;
    m.color[0] = color.x, m.color[1] = color.y, m.color[2] = color.z;
    m.pixel = pixel;
    m.kind = kind;
    m.depth = std::uint8_t(depth);
    m.flags = flags;
    const core::Vec3 inv{1.0f / ray.direction.x, 1.0f / ray.direction.y, 1.0f / ray.direction.z};
    float t0, t1;
    if (!core::intersect_bounds(s_.scene_box, ray, inv, t0, t1)) {
      m.tmax = 0;
      finish(m);
      return;
    }
    m.t_enter = t0;
    m.tmax = t1;
    m.region = map_.region_at(ScreenRay::of(s_.frame, ray.origin, ray.direction), t0);
    route(m);
  }

  void route(const RayMsg& m) {
    if (m.region == me_) {
      push(m);
      return;
    }
    ++s_.stats.work_sent;
    const std::size_t k = std::size_t(m.kind);
    if (ctx_.try_send(m.region, MessageType::kRay, m)) {
      ++s_.stats.rays_sent[k].messages;
      s_.stats.rays_sent[k].bytes += sizeof(RayMsg);
    } else {
      ctx_.send(nodes::kHost, MessageType::kRay, m);  // the paper's optimistic deadlock avoidance
      ++s_.stats.rays_spilled[k].messages;
      s_.stats.rays_spilled[k].bytes += sizeof(RayMsg);
    }
  }

  /// The ray reached its end without a hit: background or light term.
  void finish(const RayMsg& m) {
    if (m.kind == RayKind::kShadow) {
      if (m.flags & kRayHighlightSkip) ++st_.skipped.highlight_marker;
      contribute(m.pixel, core::Vec3{m.color[0], m.color[1], m.color[2]});
    } else if (!(m.flags & kRayProbeOnly)) {
      contribute(m.pixel, s_.background * m.weight);
    }
  }

  /// Traces the segment of `m` inside this node's region.
  void process(RayMsg m) {
    ++s_.stats.segments;
    const core::Vec3 o{m.origin[0], m.origin[1], m.origin[2]};
    const core::Vec3 d{m.direction[0], m.direction[1], m.direction[2]};
    std::uint32_t next = me_;
    const float t_exit = map_.exit_region(me_, ScreenRay::of(s_.frame, o, d), m.t_enter, next);
    const bool last = !(t_exit < m.tmax);
    // Eye rays start at the view's hither distance, as core's camera casts them.
    const float tmin = m.kind == RayKind::kPrimary ? std::max(query_start(m.t_enter), s_.camera.hither())
                                                   : query_start(m.t_enter);
    const core::Ray q{o, d, tmin, last ? m.tmax : t_exit};
    core::TraversalScratch& tr = s_.scratch->traversal;
    if (m.kind == RayKind::kShadow) {
      if (core::intersect_any(view_, q, tr)) return;  // blocked
    } else {
      core::Hit hit;
      if (core::intersect_closest(view_, q, hit, tr)) {
        shade(m, core::Ray{o, d, 0.0f, core::kInfinity}, hit);
        return;
      }
    }
    if (last) {
      finish(m);
      return;
    }
    if (next == me_) throw std::logic_error(fmt::format("node {}: a ray leaves region {} into itself", me_, me_));
    m.t_enter = t_exit;
    m.region = next;
    route(m);
  }

  /// core::trace_ray's terms at a hit, each child ray sent on as a message.
  void shade(const RayMsg& m, const core::Ray& ray, const core::Hit& hit) {
    const core::Primitive prim = view_.shading_primitive(hit.primitive);
    const core::Material& mat = view_.material(prim.material);
    const core::SurfaceFrame f = core::surface_frame(view_, prim, ray, hit);
    const core::Vec3& d = f.d;
    const core::Vec3& nf = f.nf;
    const core::Vec3& ns = f.ns;
    if (m.flags & kRayFirstHit) first_hit(m.pixel, std::int32_t(prim.shape), hit.t, ns);
    if (m.flags & kRayProbeOnly) return;
    const core::Vec3& above = f.above;
    const core::Vec3& below = f.below;
    const core::Vec3 v = -d;

    contribute(m.pixel, mat.color * (mat.kd * shading_.ambient_intensity) * m.weight);

    const bool highlight = mat.ks > 0.0f && mat.shine < core::kNoHighlightShine;
    for (const core::Light& light : shading_.lights) {
      const core::Vec3 to_light = light.position - above;
      const float dist = core::length(to_light);
      if (!(dist > 0.0f)) continue;
      const core::Vec3 l = to_light * (1.0f / dist);
      const float ndotl = core::dot(ns, l);
      if (ndotl <= 0.0f) {
        ++st_.skipped.shadow_backfacing;
        continue;
      }
      ++st_.rays.shadow;
      core::Vec3 c = mat.color * (mat.kd * ndotl);
      std::uint8_t flags = 0;
      if (highlight) {
        const core::Vec3 r = ns * (2.0f * ndotl) - l;
        const float rv = core::dot(r, v);
        if (rv > 0.0f) c += core::Vec3{1.0f, 1.0f, 1.0f} * (mat.ks * std::pow(rv, mat.shine));
      } else if (mat.ks > 0.0f) {
        flags = kRayHighlightSkip;
      }
      start_ray(core::Ray{above, to_light, 0.0f, 1.0f}, RayKind::kShadow, m.pixel, m.depth, m.weight,
                c * light.color * shading_.light_intensity * m.weight, flags);
    }

    auto may_spawn = [&](float w) {
      if (m.depth >= shading_.max_depth) {
        ++st_.skipped.depth_limit;
        return false;
      }
      if (w < shading_.min_weight) {
        ++st_.skipped.min_weight;
        return false;
      }
      return true;
    };
    auto reflect_dir = [&]() {
      core::Vec3 r = d - ns * (2.0f * core::dot(d, ns));
      if (core::dot(r, nf) <= 0.0f) r = d - nf * (2.0f * core::dot(d, nf));
      return r;
    };
    if (mat.ks > 0.0f) {
      const float w = m.weight * mat.ks;
      if (may_spawn(w)) {
        const core::Ray r{above, reflect_dir(), 0.0f, core::kInfinity};
        if (core::is_valid_ray(r)) {
          ++st_.rays.reflected;
          start_ray(r, RayKind::kReflected, m.pixel, m.depth + 1, w, core::Vec3{}, 0);
        }
      }
    } else {
      ++st_.skipped.reflection_ks0;
    }
    if (mat.transmittance > 0.0f) {
      const float w = m.weight * mat.transmittance;
      if (may_spawn(w)) {
        const float ior = mat.ior > 0.0f ? mat.ior : 1.0f;
        const float eta = f.front ? 1.0f / ior : ior;
        core::Vec3 dir;
        const bool tir = !core::refract(d, ns, eta, dir);
        if (tir) dir = reflect_dir();
        const core::Ray r{core::dot(dir, nf) > 0.0f ? above : below, dir, 0.0f, core::kInfinity};
        if (core::is_valid_ray(r)) {
          ++st_.rays.refracted;
          if (tir) ++st_.rays.refracted_tir;
          start_ray(r, RayKind::kRefracted, m.pixel, m.depth + 1, w, core::Vec3{}, 0);
        }
      }
    } else {
      ++st_.skipped.refraction_t0;
    }
  }

  void contribute(std::uint32_t pixel, const core::Vec3& c) {
    if (n_contrib_ == s_.contributions.size()) flush_contributions();
    s_.contributions[n_contrib_++] = Contribution{pixel, {c.x, c.y, c.z}};
    ++s_.stats.contributions;
  }

  void first_hit(std::uint32_t pixel, std::int32_t shape, float t, const core::Vec3& n) {
    if (n_first_ == s_.first_hits.size()) flush_first_hits();
    s_.first_hits[n_first_++] = FirstHitRecord{pixel, shape, me_, t, {n.x, n.y, n.z}};
  }

  void flush_contributions() {
    if (n_contrib_ == 0) return;
    ctx_.send(nodes::kHost, MessageType::kContribution, ContributionHeader{0, std::uint32_t(n_contrib_)},
              std::as_bytes(std::span<const Contribution>(s_.contributions.data(), n_contrib_)));
    ++s_.stats.contribution_messages;
    ++s_.stats.work_sent;
    n_contrib_ = 0;
  }
  void flush_first_hits() {
    if (n_first_ == 0) return;
    ctx_.send(nodes::kHost, MessageType::kContribution, ContributionHeader{1, std::uint32_t(n_first_)},
              std::as_bytes(std::span<const FirstHitRecord>(s_.first_hits.data(), n_first_)));
    ++s_.stats.work_sent;
    n_first_ = 0;
  }
  void flush() {
    flush_contributions();
    flush_first_hits();
  }

  bool want_first_hit_;
  NodeContext& ctx_;
  NodeState& s_;
  std::uint32_t me_;
  RegionView view_;
  RegionMap map_;
  core::ShadingContext shading_;
  core::RenderStats& st_;
  static constexpr std::uint64_t kYieldEvery = 16;
  std::uint64_t units_ = 0;
  std::size_t stack_size_ = 0, n_contrib_ = 0, n_first_ = 0;
  std::size_t inbox_head_ = 0, inbox_size_ = 0;
  double clock_ = 0;  ///< the node's clock when last sampled (only ever behind)
  static constexpr std::uint64_t kClockEvery = 8;
  std::uint64_t stale_ = 0;
  bool probe_pending_ = false;
  std::uint32_t probe_wave_ = 0;
};

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

/// A spilled ray waiting at the host.
struct Stored {
  RayMsg ray;
  double depart;
};

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

  nodes::MachineParams mp = params.machine;
  mp.max_payload = std::max<std::uint32_t>(mp.max_payload, 256);
  if (mp.mailbox_capacity == 0) mp.mailbox_capacity = kDefaultQueueCapacity;
  // Rays are not waited for: serve them when a core is free (machine.h).
  if (!mp.scheduled_mail) mp.scheduled_mail = true;
  nodes::Machine machine(mp);  // validates the node count, sets the default mailbox capacity
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
  ep.regions = n;
  out.estimate = estimate_load(db, grid, camera, frame, extent, ep);
  out.extent = extent;

  // 2. Partition and the regions' databases.
  const auto t0 = std::chrono::steady_clock::now();
  const CostGrid cut_cost = params.partition == PartitionKind::kEqual
                                ? uniform_cost(extent, params.estimate_resolution)
                                : out.estimate.cost;
  Partition partition = make_partition(frame, cut_cost, n);
  // A refined estimate's cuts cover only where the work is: the outer
  // regions' finite rectangles reach on to the scene's extent, which their
  // local grids must cover.
  for (std::uint32_t r = 0; r < partition.region_count(); ++r) {
    const ScreenRect& own = partition.rects[r];
    ScreenRect& f = partition.finite[r];
    if (std::isinf(own.x0)) f.x0 = std::min(f.x0, extent.x0);
    if (std::isinf(own.y0)) f.y0 = std::min(f.y0, extent.y0);
    if (std::isinf(own.x1)) f.x1 = std::max(f.x1, extent.x1);
    if (std::isinf(own.y1)) f.y1 = std::max(f.y1, extent.y1);
  }
  partition.extent = extent;
  std::vector<RegionDatabase> regions = make_region_databases(db, partition, params.grid);
  const RegionMap map = partition.map();

  // 3. Own primary rays: each sample goes to the region where it enters the scene.
  const core::Bounds3 scene_box = grid.info.bounds;
  const bool want_first = rp.any_aov() || params.region_aov;
  const std::uint32_t samples = std::uint32_t(rp.spp * rp.spp) + ((want_first && rp.spp % 2 == 0) ? 1u : 0u);
  std::vector<std::vector<PrimarySample>> primaries(n);
  for (std::uint32_t pixel = 0; pixel < std::uint32_t(w) * std::uint32_t(h); ++pixel)
    for (std::uint32_t k = 0; k < samples; ++k) {
      const core::Ray ray = primary_ray(camera, rp.spp, pixel, k);
      const core::Vec3 inv{1.0f / ray.direction.x, 1.0f / ray.direction.y, 1.0f / ray.direction.z};
      float ta, tb;
      const std::uint32_t owner = core::intersect_bounds(scene_box, ray, inv, ta, tb)
                                      ? map.region_at(ScreenRay::of(frame, ray.origin, ray.direction), ta)
                                      : pixel % n;
      primaries[owner].push_back(PrimarySample{pixel, k});
    }

  // Fail early, with the sizes, when a region does not fit its node.
  const NodeBudget budget = node_budget(m, db.lights.size(), rp.max_depth, n, partition.tree.size());
  out.regions.resize(n);
  for (std::uint32_t r = 0; r < n; ++r) {
    RegionReport& rr = out.regions[r];
    const RegionDatabase& rd = regions[r];
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
    rr.estimated_cost = cost_in(out.estimate.cost, partition.finite[r]);
    const std::size_t need = rr.bytes + primaries[r].size() * sizeof(PrimarySample) + budget.fixed;
    if (need > m.node_memory)
      throw nodes::DoesNotFit(
          fmt::format("dataflow mode: region {} needs {} ({} B: {} primitives, {} ({}), {} own primary rays, {} for "
                      "the mailbox and buffers), --node-memory is {} ({} B)",
                      r, nodes::format_bytes(need), need, rr.primitives, grid_phrase(rr),
                      nodes::format_bytes(rr.grid_bytes), primaries[r].size(), nodes::format_bytes(budget.fixed),
                      nodes::format_bytes(m.node_memory), m.node_memory),
          need, m.node_memory);
  }
  out.setup_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  // Frame buffer and AOVs on the host.
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
  if (params.region_aov) {
    out.region = core::Image(w, h, 1);
    std::fill(out.region.pixels.begin(), out.region.pixels.end(), -1.0f);
  }
  std::vector<double> sums(std::size_t(w) * h * 3, 0.0);

  std::vector<std::unique_ptr<NodeState>> states(n);
  auto setup = [&](NodeContext& ctx) {
    Arena& a = ctx.arena();
    const RegionDatabase& rd = regions[ctx.id()];
    auto s = std::make_unique<NodeState>(camera);
    s->arena = &a;
    s->progress = rp.progress;
    s->grid = rd.grid.info;
    s->background = db.background;
    s->scene_box = scene_box;
    s->frame = frame;
    s->spp = rp.spp;
    s->max_depth = rp.max_depth;
    s->min_weight = rp.min_weight;
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
      s->top_sub_grid_bits = nodes::copy_to_arena(a, std::span<const std::uint64_t>(rd.grid.top_sub_grid_bits),
                                                  "the region's top cells' sub-grid bits");
    }
    s->shared = nodes::copy_to_arena(a, std::span<const std::uint8_t>(rd.shared), "the shared-primitive flags");
    s->lights = nodes::copy_to_arena(a, std::span<const core::Light>(db.lights), "the lights");
    s->tree = nodes::copy_to_arena(a, std::span<const KdNode>(partition.tree), "the region tree");
    s->rects = nodes::copy_to_arena(a, std::span<const ScreenRect>(partition.rects), "the region rectangles");
    s->primaries = nodes::copy_to_arena(a, std::span<const PrimarySample>(primaries[ctx.id()]), "its primary rays");
    s->stack = ArenaArray<RayMsg>(a, budget.stack_slots, "its ray stack");
    s->inbox = ArenaArray<Pending>(a, budget.inbox_slots, "its inbox");
    s->contributions = ArenaArray<Contribution>(a, budget.contribution_slots, "its contribution buffer");
    s->first_hits = ArenaArray<FirstHitRecord>(a, budget.first_hit_slots, "its first-hit buffer");
    s->scratch = a.create<core::ShadingScratch>("its tracing scratch");
    s->cost_model = machine.params().cost_model;
    states[ctx.id()] = std::move(s);
  };

  auto node_main = [&](NodeContext& ctx) {
    ctx.set_work_meter(&NodeState::work_seconds, states[ctx.id()].get());
    ctx.set_park_limit(std::min<std::size_t>(m.mailbox_capacity, kParkLimit));
    NodeTracer(ctx, *states[ctx.id()], want_first).run();
  };

  auto host_main = [&](NodeContext& host) {
    HostFlowStats& hs = out.host;
    std::vector<std::deque<Stored>> store(n);
    std::uint64_t stored = 0, sent = 0, received = 0;
    const double service = host.network().service_s;
    // Termination waves (Mattern's four counters).
    std::uint32_t wave = 1, replies = 0;
    std::uint64_t wave_sent = 0, wave_received = 0, prev_sent = 0, prev_received = 0;
    bool have_prev = false;
    std::vector<NodeId> probes;  // still to be sent for the current wave
    auto start_wave = [&] {
      replies = 0;
      wave_sent = wave_received = 0;
      probes.clear();
      for (NodeId i = n; i-- > 0;) probes.push_back(i);
    };
    start_wave();
    bool done = false;
    auto handle = [&](const Message& msg) {
      switch (msg.type()) {
        case MessageType::kRay: {
          const RayMsg r = msg.as<RayMsg>();
          if (r.region >= n) throw std::logic_error(fmt::format("host: a spilled ray for region {}", r.region));
          store[r.region].push_back(Stored{r, msg.header.arrival_time + service});
          ++stored;
          ++received;
          ++hs.spilled;
          hs.store_peak = std::max(hs.store_peak, stored);
          break;
        }
        case MessageType::kContribution: {
          const ContributionHeader head = msg.as<ContributionHeader>();
          const std::span<const std::byte> tail = msg.tail<ContributionHeader>();
          const std::size_t rec = head.kind == 0 ? sizeof(Contribution) : sizeof(FirstHitRecord);
          if (tail.size() != head.count * rec)
            throw std::logic_error(fmt::format("host: a contribution message of {} B for {} records", tail.size(),
                                               head.count));
          ++received;
          for (std::uint32_t i = 0; i < head.count; ++i) {
            if (head.kind == 0) {
              Contribution c;
              std::memcpy(&c, tail.data() + i * rec, rec);
              if (c.pixel >= std::uint32_t(w) * std::uint32_t(h))
                throw std::logic_error(fmt::format("host: a contribution to pixel {}", c.pixel));
              double* s = &sums[std::size_t(c.pixel) * 3];
              s[0] += c.rgb[0], s[1] += c.rgb[1], s[2] += c.rgb[2];
              ++hs.contributions;
            } else {
              FirstHitRecord f;
              std::memcpy(&f, tail.data() + i * rec, rec);
              const int x = int(f.pixel % std::uint32_t(w)), y = int(f.pixel / std::uint32_t(w));
              if (!out.render.depth.empty()) *out.render.depth.at(x, y) = f.t;
              if (!out.render.normal.empty()) std::memcpy(out.render.normal.at(x, y), f.normal, 3 * sizeof(float));
              if (!out.render.primitive.empty()) *out.render.primitive.at(x, y) = float(f.shape);
              if (!out.region.empty()) *out.region.at(x, y) = float(f.region);
              ++hs.first_hits;
            }
          }
          break;
        }
        case MessageType::kToken: {
          const TokenMsg t = msg.as<TokenMsg>();
          if (t.wave != wave)
            throw std::logic_error(fmt::format("host: an answer to wave {} during wave {}", t.wave, wave));
          wave_sent += t.sent;
          wave_received += t.received;
          if (++replies < n) break;
          ++hs.waves;
          const std::uint64_t s_total = wave_sent + sent, r_total = wave_received + received;
          if (stored == 0 && s_total == r_total && have_prev && prev_sent == s_total && prev_received == r_total) {
            done = true;
            break;
          }
          prev_sent = s_total, prev_received = r_total, have_prev = true;
          ++wave;
          start_wave();
          break;
        }
        default:
          throw std::logic_error(fmt::format("host: unexpected {} message from {}",
                                             nodes::message_type_name(msg.type()), nodes::node_name(msg.source())));
      }
    };
    Message msg;
    while (!done) {
      // Forward what the host keeps, as far as the mailboxes have room.
      if (stored > 0)
        for (NodeId dest = 0; dest < n; ++dest) {
          auto& q = store[dest];
          while (!q.empty()) {
            if (!host.try_send(dest, MessageType::kRay, q.front().ray, {}, q.front().depart)) {
              ++hs.forward_retries;
              break;
            }
            q.pop_front();
            --stored;
            ++sent;
            ++hs.forwarded;
          }
        }
      while (!probes.empty() && host.try_send(probes.back(), MessageType::kToken, TokenMsg{wave, 0, 0, 0}, {}, 0.0))
        probes.pop_back();
      if (host.poll(msg)) {
        handle(msg);
        continue;
      }
      // Nothing came: wait for mail; with rays or probes still to send, retry soon.
      host.wait_for_mail(stored > 0 || !probes.empty() ? 1e-4 : 0.0);
    }
    for (NodeId i = 0; i < n; ++i) host.send(i, MessageType::kShutdown, TokenMsg{wave, 0, 0, 0}, {}, 0.0);
  };

  out.per_node.resize(n);
  out.run = machine.run(node_main, host_main, setup, [&](NodeContext& ctx) {
    if (states[ctx.id()]) out.per_node[ctx.id()] = states[ctx.id()]->stats;
    states[ctx.id()].reset();
  });

  const float inv = 1.0f / float(rp.spp * rp.spp);
  for (std::size_t i = 0; i < std::size_t(w) * h; ++i)
    for (int c = 0; c < 3; ++c) out.render.color.pixels[i * 3 + c] = float(sums[i * 3 + c]) * inv;
  for (const NodeFlowStats& s : out.per_node) out.render.stats += s.tracing;
  return out;
}

std::uint64_t DataflowResult::ray_messages() const {
  std::uint64_t t = 0;
  for (const NodeFlowStats& s : per_node)
    for (int k = 0; k < kRayKindCount; ++k) t += s.rays_sent[k].messages + s.rays_spilled[k].messages;
  return t;
}

double DataflowResult::spill_fraction() const {
  const std::uint64_t all = ray_messages();
  return all ? double(host.spilled) / double(all) : 0.0;
}

std::vector<double> DataflowResult::measured_load() const {
  std::vector<double> load;
  for (const nodes::NodeReport& r : run.nodes)
    load.push_back(run.parallel_time_s > 0 ? r.counters.busy_s / run.parallel_time_s : 0.0);
  return load;
}

double DataflowResult::average_load() const {
  const std::vector<double> l = measured_load();
  double s = 0;
  for (double v : l) s += v;
  return l.empty() ? 0.0 : s / double(l.size());
}

nlohmann::json DataflowResult::to_json() const {
  nlohmann::json j;
  j["partition"] = partition_name(partition);
  j["regions"] = regions.size();
  j["estimate"] = {{"pixels", estimate.pixels},
                   {"rays", estimate.rays},
                   {"host_s", estimate.seconds},
                   {"cost_grid", {estimate.cost.nx, estimate.cost.ny}},
                   {"cost_extent", {estimate.cost.extent.x0, estimate.cost.extent.y0, estimate.cost.extent.x1,
                                    estimate.cost.extent.y1}},
                   {"refined", estimate.refined},
                   {"total_cost", estimate.cost.total()}};
  j["setup_s"] = setup_s;
  nlohmann::json by_kind = nlohmann::json::object();
  std::uint64_t shared_tests = 0, contributions = 0, contribution_messages = 0, segments = 0;
  for (int k = 0; k < kRayKindCount; ++k) {
    std::uint64_t msgs = 0, bytes = 0, spilled = 0, received = 0;
    for (const NodeFlowStats& s : per_node) {
      msgs += s.rays_sent[k].messages;
      bytes += s.rays_sent[k].bytes + s.rays_spilled[k].bytes;
      spilled += s.rays_spilled[k].messages;
      received += s.rays_received[k];
    }
    by_kind[ray_kind_name(RayKind(k))] = {
        {"messages", msgs + spilled}, {"bytes", bytes}, {"spilled", spilled}, {"received", received}};
  }
  for (const NodeFlowStats& s : per_node) {
    shared_tests += s.shared_tests;
    contributions += s.contributions;
    contribution_messages += s.contribution_messages;
    segments += s.segments;
  }
  j["ray_messages"] = by_kind;
  j["ray_messages_total"] = ray_messages();
  j["ray_segments"] = segments;
  j["contributions"] = contributions;
  j["contribution_messages"] = contribution_messages;
  j["host"] = {{"spilled", host.spilled},           {"forwarded", host.forwarded},
               {"forward_retries", host.forward_retries}, {"store_peak", host.store_peak},
               {"contributions", host.contributions},    {"first_hits", host.first_hits},
               {"termination_waves", host.waves}};
  j["spill_fraction"] = spill_fraction();
  std::size_t held = 0, shared_prims = 0;
  for (const RegionReport& r : regions) held += r.primitives, shared_prims += r.shared_primitives;
  j["primitives_held"] = held;
  j["shared_primitive_copies"] = shared_prims;
  j["shared_primitive_tests"] = shared_tests;
  const std::vector<double> load = measured_load();
  double est_total = 0, busy_total = 0;
  for (const RegionReport& r : regions) est_total += r.estimated_cost;
  for (const nodes::NodeReport& r : run.nodes) busy_total += r.counters.busy_s;
  nlohmann::json per = nlohmann::json::array();
  for (std::size_t i = 0; i < regions.size(); ++i) {
    const RegionReport& r = regions[i];
    const double busy = i < run.nodes.size() ? run.nodes[i].counters.busy_s : 0.0;
    // rect: screen frame, within the extent; grid_resolution: an adaptive grid's top grid.
    nlohmann::json region = {{"region", i},
                             {"node", r.node},
                             {"rect", {r.finite.x0, r.finite.y0, r.finite.x1, r.finite.y1}},
                             {"primitives", r.primitives},
                             {"shared_primitives", r.shared_primitives},
                             {"grid_kind", core::grid_kind_name(r.grid_kind)},
                             {"grid_resolution", {r.grid_res[0], r.grid_res[1], r.grid_res[2]}},
                             {"grid_references", r.grid_references},
                             {"grid_bytes", r.grid_bytes},
                             {"bytes", r.bytes},
                             {"estimated_share", est_total > 0 ? r.estimated_cost / est_total : 0.0},
                             {"measured_share", busy_total > 0 ? busy / busy_total : 0.0},
                             {"busy_s", busy},
                             {"load", i < load.size() ? load[i] : 0.0},
                             {"primaries", i < per_node.size() ? per_node[i].primaries : 0},
                             {"segments", i < per_node.size() ? per_node[i].segments : 0}};
    if (r.grid_kind == core::GridKind::kAdaptive) {
      region["grid_sub_grids"] = r.grid_sub_grids;
      region["grid_leaf_cells"] = r.grid_leaf_cells;
    }
    per.push_back(std::move(region));
  }
  double max_busy = 0;
  for (const nodes::NodeReport& r : run.nodes) max_busy = std::max(max_busy, r.counters.busy_s);
  j["average_load"] = average_load();
  j["balance"] = max_busy > 0 && !run.nodes.empty() ? busy_total / double(run.nodes.size()) / max_busy : 0.0;
  j["per_region"] = std::move(per);
  return j;
}

}  // namespace raynode::dataflow
