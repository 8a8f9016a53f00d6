#include "dataflow/node_tracer.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <span>
#include <stdexcept>
#include <thread>

#include "dataflow/region_view.h"
#include "nodes/mailbox.h"

namespace raynode::dataflow {

using nodes::Message;
using nodes::MessageType;
using nodes::NodeContext;

core::Ray primary_ray(const core::Camera& camera, int spp, std::uint32_t pixel, std::uint32_t sample) {
  const int x = int(pixel % std::uint32_t(camera.width())), y = int(pixel / std::uint32_t(camera.width()));
  if (sample == std::uint32_t(spp * spp)) return camera.ray_through(float(x) + 0.5f, float(y) + 0.5f);
  const float n = float(spp);
  const int i = int(sample % std::uint32_t(spp)), j = int(sample / std::uint32_t(spp));
  return camera.ray_through(float(x) + (float(i) + 0.5f) / n, float(y) + (float(j) + 0.5f) / n);
}


NodeBudget node_budget(const nodes::MachineParams& m, std::size_t lights, int max_depth, std::uint32_t regions,
                       std::size_t tree_nodes, std::size_t send_queue_slots) {
  NodeBudget b;
  b.stack_slots = 2 + (lights + 2) * std::size_t(max_depth + 1);
  b.inbox_slots = std::max<std::size_t>(1, 4 * std::size_t(m.mailbox_capacity));
  b.send_queue_slots = send_queue_slots > 0 ? send_queue_slots : std::max<std::size_t>(1, m.mailbox_capacity);
  b.send_queue_fixed = send_queue_slots > 0;
  // Room for messages parked while a send to the host waits (node.h;
  // bounded by set_park_limit, kParkLimit).
  b.parking = std::min<std::size_t>(m.mailbox_capacity, kParkLimit) * (m.max_payload + 96);
  b.contribution_slots = (m.max_payload - sizeof(ContributionHeader)) / sizeof(Contribution);
  b.first_hit_slots = (m.max_payload - sizeof(ContributionHeader)) / sizeof(FirstHitRecord);
  b.fixed = nodes::Mailbox::bytes_for(m.mailbox_capacity, m.max_payload) + m.max_payload +
            b.stack_slots * sizeof(RayMsg) + b.inbox_slots * sizeof(Pending) +
            b.send_queue_slots * SendQueue::kSlotBytes + SendQueue::destination_bytes(m.nodes) +
            b.contribution_slots * sizeof(Contribution) + b.first_hit_slots * sizeof(FirstHitRecord) +
            tree_nodes * sizeof(KdNode) +
            std::size_t(regions) * sizeof(ScreenRect) + lights * sizeof(core::Light) + sizeof(core::ShadingScratch) +
            b.parking;
  return b;
}

namespace {

/// The lower end of a region's query: a little before t_enter, so that a hit
/// exactly on the region boundary is not lost to rounding (a hit before
/// t_enter would have ended the ray in the previous region).
inline float query_start(float t_enter) { return std::max(0.0f, t_enter - 1e-5f * t_enter); }

/// A node's side of the frame: its receiving queue, local ray stack, own
/// primary rays, routing and shading (dataflow.h).
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
                                            s.min_weight, s.shadow_rays)),
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
      // The communication task: rays waiting in the sending queue go out
      // once their destination has room (every few rays, and when passive).
      if (!s_.send_queue.empty() && ++drain_tick_ % kDrainEvery == 0) drain_send_queue();
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
      if (!s_.send_queue.empty() && (drain_send_queue(), !s_.send_queue.empty())) {
        // Rays still wait for room: not passive. Let the others run (their
        // mailboxes drain only when they do) and try again shortly.
        ctx_.release_run();
        ctx_.wait_for_mail(kSendRetryS);
        ctx_.reset_cpu_mark();
        continue;
      }
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
        if (stack_size_ > 0 || inbox_size_ > 0 || !s_.send_queue.empty())
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
                 const core::Vec3& color, std::uint8_t flags, std::uint32_t origin_triangle = core::kNoPrimitive) {
    RayMsg m;
    m.origin_triangle = origin_triangle;
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

  /// Hands `m` to its region's owner: this node's own queue, the owner's
  /// mailbox, the sending queue or the host (the paper's spill).
  void route(RayMsg m) {
    if (m.region == me_) {
      push(m);
      return;
    }
    m.origin_triangle = core::kNoPrimitive;  // an id local to this region: no other region's
    ++s_.stats.work_sent;
    if (s_.send_queue.empty() && try_send_ray(m)) return;
    // The destination is full (or rays wait before this one): the sending
    // queue holds the ray; when the queue itself is full, the paper's
    // optimistic deadlock avoidance sends it to the host.
    if (s_.send_queue.size() == s_.send_queue.capacity()) drain_send_queue();
    if (s_.send_queue.push(m)) {
      ++s_.stats.rays_queued;
      s_.stats.send_queue_peak = std::max<std::uint64_t>(s_.stats.send_queue_peak, s_.send_queue.size());
      return;
    }
    const std::size_t k = std::size_t(m.kind);
    ctx_.send(nodes::kHost, MessageType::kRay, m);
    ++s_.stats.rays_spilled[k].messages;
    s_.stats.rays_spilled[k].bytes += sizeof(RayMsg);
  }

  /// Sends `m` to its region's owner if its mailbox has room.
  bool try_send_ray(const RayMsg& m) {
    if (!ctx_.try_send(m.region, MessageType::kRay, m)) return false;
    const std::size_t k = std::size_t(m.kind);
    ++s_.stats.rays_sent[k].messages;
    s_.stats.rays_sent[k].bytes += sizeof(RayMsg);
    return true;
  }

  /// The communication task: queued rays whose destination has room leave.
  void drain_send_queue() {
    s_.send_queue.drain([this](const RayMsg& r) { return try_send_ray(r); });
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
      if (core::intersect_any(view_, q, tr, m.origin_triangle)) return;  // blocked
    } else {
      core::Hit hit;
      if (core::intersect_closest(view_, q, hit, tr, m.origin_triangle)) {
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

  /// core's shading at a hit (core::shade_hit), each shadow and child ray
  /// sent on as a message carrying its weighted contribution.
  void shade(const RayMsg& m, const core::Ray& ray, const core::Hit& hit) {
    const core::Primitive prim = view_.shading_primitive(hit.primitive);
    const core::Material& mat = view_.material(prim.material);
    const core::SurfaceFrame f = core::surface_frame(view_, prim, ray, hit);
    if (m.flags & kRayFirstHit) first_hit(m.pixel, std::int32_t(prim.shape), hit.t, f.ns);
    if (m.flags & kRayProbeOnly) return;
    contribute(m.pixel, core::ambient_term(shading_, mat) * m.weight);
    core::shade_hit(
        shading_, mat, f, m.depth, m.weight, st_,
        [&](const core::Ray& shadow, auto&& light_term, bool highlight_skipped) {
          start_ray(shadow, RayKind::kShadow, m.pixel, m.depth, m.weight, light_term() * m.weight,
                    highlight_skipped ? kRayHighlightSkip : std::uint8_t(0), f.leaving(shadow));
        },
        [&](core::ChildKind kind, const core::Ray& r, float w) {
          start_ray(r, kind == core::ChildKind::kReflected ? RayKind::kReflected : RayKind::kRefracted, m.pixel,
                    m.depth + 1, w, core::Vec3{}, 0, f.leaving(r));
        });
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
  static constexpr std::uint64_t kDrainEvery = 8;  ///< loop turns between passes over a non-empty sending queue
  std::uint64_t drain_tick_ = 0;
  static constexpr double kSendRetryS = 50e-6;  ///< wall seconds a passive node with queued rays waits before it tries again
  double clock_ = 0;  ///< the node's clock when last sampled (only ever behind)
  static constexpr std::uint64_t kClockEvery = 8;
  std::uint64_t stale_ = 0;
  bool probe_pending_ = false;
  std::uint32_t probe_wave_ = 0;
};

}  // namespace

void run_node_tracer(NodeContext& ctx, NodeState& s, bool want_first_hit) { NodeTracer(ctx, s, want_first_hit).run(); }

}  // namespace raynode::dataflow
