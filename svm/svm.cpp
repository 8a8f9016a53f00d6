#include "svm/svm.h"

#include <fmt/core.h>

#include <algorithm>
#include <exception>
#include <cmath>
#include <cstring>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "core/camera.h"
#include "core/shade.h"
#include "control/image_frame.h"
#include "control/pixel_record.h"
#include "svm/paged_view.h"

namespace raynode::svm {

using nodes::NodeContext;
using control::Rect;

namespace {

/// Arena bytes kept free for messages parked at run time (a blocking send
/// parks the node's incoming mail; a page fault sets work messages aside).
std::size_t message_reserve(std::uint32_t max_payload) { return 32 * 1024 + 2 * std::size_t(max_payload); }

/// What a node holds besides the pager: O(1) metadata by value, the
/// replicated materials and lights in its arena.
struct NodeState {
  NodeState(const core::TopGridInfo& g, const core::Camera& c, const core::Vec3& bg, const core::RenderParams& p,
            const Rect& submap)
      : grid(g), camera(c), background(bg), render(p), submap(submap) {}
  core::TopGridInfo grid;
  core::Camera camera;
  core::Vec3 background;
  core::RenderParams render;
  Rect submap;
  nodes::ArenaArray<core::Material> materials;
  nodes::ArenaArray<core::Light> lights;
  nodes::ArenaArray<std::int32_t> cell_keys;  ///< bricked directory: CellKeyTables' words
  core::CellKeyTables cell_order;
  control::PixelBatch batch;  ///< outgoing pixel blocks (one message's payload)
  Pager* pager = nullptr;
  core::ShadingScratch* scratch = nullptr;
  nodes::Arena* arena = nullptr;
  core::RenderStats stats;
  control::WorkStats work;
  PagerStats pager_stats;
  core::CostModel cost_model;

  /// The model clock's work meter (NodeContext::set_work_meter): the
  /// tracer's operations plus the pager's accesses, accesses to cached
  /// pages, LRU updates and faults.
  static double work_seconds(const void* self) {
    const NodeState& s = *static_cast<const NodeState*>(self);
    core::CostCounts c = core::cost_counts(s.scratch->stats.rays, s.scratch->traversal.stats);
    const PagerStats& p = s.pager->stats();
    c[std::size_t(core::CostFeature::kPageAccess)] = double(p.accesses);
    c[std::size_t(core::CostFeature::kLruUpdate)] = double(p.lru_updates());
    c[std::size_t(core::CostFeature::kPageFault)] = double(p.misses);
    c[std::size_t(core::CostFeature::kCachePageAccess)] = double(p.cache_page_accesses);
    return s.cost_model.seconds(c);
  }

  ~NodeState() {
    if (arena) {
      arena->destroy(scratch);
      arena->destroy(pager);
    }
  }
};

/// Everything the run needs from the host, none of it the host's scene.
struct RunInput {
  const PagedImage* image;
  core::TopGridInfo grid;
  std::span<const core::Material> materials;
  std::span<const core::Light> lights;
  core::Vec3 background;
  core::Camera camera;
};

}  // namespace

PagerStats SvmResult::pager_total() const {
  PagerStats t;
  for (const PagerStats& p : pager) t += p;
  return t;
}

std::uint32_t cache_frames_for(const PageLayout& layout, const SvmParams& params, std::uint32_t node,
                               std::size_t fixed) {
  const std::uint32_t n = params.machine.nodes;
  const std::size_t budget = params.machine.node_memory;
  const std::size_t ps = layout.page_size;
  const std::size_t frame_cost = ps + kPagerFrameOverheadBytes;
  const std::uint32_t home = layout.home_pages(node, n);
  const std::uint32_t useful = layout.pages - home;  // more cache than this is never used
  const std::size_t home_bytes = std::size_t(home) * ps;
  const std::size_t need_min = fixed + home_bytes + (useful > 0 ? frame_cost : 0);
  if (need_min > budget) {
    const std::size_t per_node_pages =
        budget > fixed + (n > 1 ? frame_cost : 0) ? (budget - fixed - (n > 1 ? frame_cost : 0)) / ps : 0;
    const std::size_t hold = per_node_pages * ps * n;
    // When a node's own overhead leaves no room for a page, more nodes do not
    // help: its mailbox grows with the node count (2 slots per node).
    const char* advice = per_node_pages > 0 ? "use more nodes, more --node-memory or a smaller scene"
                         : n > 1            ? "use more --node-memory or fewer nodes (each node's mailbox grows "
                                              "with the node count)"
                                            : "use more --node-memory";
    throw nodes::DoesNotFit(
        fmt::format("svm mode: the database needs {} ({} pages of {} B), {} {} x {} hold {} for pages (each node "
                    "keeps {} for its page table, mailbox and buffers{}); {}",
                    nodes::format_bytes(layout.bytes()), layout.pages, ps, n, n == 1 ? "node" : "nodes",
                    nodes::format_bytes(budget), nodes::format_bytes(hold), nodes::format_bytes(fixed),
                    n > 1 ? ", and one cache page" : "", advice),
        layout.bytes(), hold);
  }
  // Frames beyond the pager's 4 GiB (with the list buffer) are never given.
  const std::size_t addressable = kPagerMaxFrameBytes / ps > home + 1 ? kPagerMaxFrameBytes / ps - home - 1 : 0;
  const std::size_t fit = std::min((budget - fixed - home_bytes) / frame_cost, addressable);
  const bool explicit_cache = params.cache_pages > 0 || params.cache_fraction > 0;
  if (!explicit_cache) return std::uint32_t(std::min<std::size_t>(fit, useful));
  std::uint64_t want = params.cache_pages;
  if (params.cache_fraction > 0)
    want = std::max<std::uint64_t>(1, std::uint64_t(std::ceil(params.cache_fraction * double(layout.pages))));
  want = std::min<std::uint64_t>(want, useful);
  if (want > fit)
    throw nodes::DoesNotFit(
        fmt::format("svm mode: a cache of {} pages of {} B does not fit in {}: --node-memory is {}, its {} home "
                    "pages take {} and its page table, mailbox and buffers {}, which leaves room for {} cache pages",
                    want, ps, nodes::node_name(node), nodes::format_bytes(budget), home,
                    nodes::format_bytes(home_bytes), nodes::format_bytes(fixed), fit),
        std::size_t(want) * ps + home_bytes + fixed, budget);
  return std::uint32_t(want);
}

namespace {

/// The host's paged image of `db` (with --pack-cells, the packed cells'
/// triangle blocks paged too), its cell directory in `order`, its
/// primitives in params.primitive_order (auto: SvmParams::primitive_order).
PagedImage page_database(const core::Database& db, const core::Grid& grid, const SvmParams& params,
                         DirectoryOrder order) {
  const core::CellBlocks blocks = params.pack_min ? core::build_cell_blocks(db, grid, params.pack_min) : core::CellBlocks{};
  const core::CellBlocks* packed = params.pack_min ? &blocks : nullptr;
  PrimitiveOrder primitives = params.primitive_order.value_or(PrimitiveOrder::kFile);
  if (!params.primitive_order && grid.kind() == core::GridKind::kAdaptive)
    primitives = fewer_list_pages(grid, make_page_layout(db, grid, params.page_size, packed, order));
  return build_paged_image(db, grid, params.page_size, packed, order, primitives);
}

/// A node's bytes besides its home pages and cache frames: mailbox, receive
/// buffer, page table, pager, materials, lights, pixel batch, scratch, the
/// bricked directory's key tables, parked messages and the work farm.
std::size_t node_fixed_bytes(const nodes::MachineParams& m, const PageLayout& layout, const RunInput& in,
                             std::span<const Rect> submaps, const SvmParams& params) {
  return nodes::Mailbox::bytes_for(m.mailbox_capacity, m.max_payload) + m.max_payload + pager_table_bytes(layout, 0) +
         sizeof(Pager) + in.materials.size_bytes() + in.lights.size_bytes() + control::PixelBatch::bytes(m.max_payload) +
         sizeof(core::ShadingScratch) +
         (layout.directory_order == DirectoryOrder::kBricked ? core::CellKeyTables::words(in.grid) * sizeof(std::int32_t)
                                                             : 0) +
         message_reserve(m.max_payload) + control::work_farm_bytes(nodes::resolved_work_grant(m), submaps, params.item_w, params.item_h);
}

/// A node's state in its arena, loaded by the host (outside virtual time):
/// the metadata, the bricked directory's key tables, its buffers, and its
/// pager with `cache_frames` frames and its home pages copied in; its pixel
/// batch holds one message of `max_payload` bytes.
std::unique_ptr<NodeState> make_node_state(NodeContext& ctx, const RunInput& in, const core::RenderParams& rp,
                                           const Rect& submap, const core::CostModel& cost_model,
                                           std::uint32_t cache_frames, std::uint32_t max_payload) {
  nodes::Arena& a = ctx.arena();
  const PageLayout& layout = in.image->layout;
  auto s = std::make_unique<NodeState>(in.grid, in.camera, in.background, rp, submap);
  s->arena = &a;
  s->materials = nodes::copy_to_arena(a, in.materials, "the materials");
  s->lights = nodes::copy_to_arena(a, in.lights, "the lights");
  if (layout.directory_order == DirectoryOrder::kBricked) {
    s->cell_keys = nodes::ArenaArray<std::int32_t>(a, core::CellKeyTables::words(in.grid), "the cell key tables");
    s->cell_order = core::CellKeyTables::build(in.grid, layout.bricks, s->cell_keys.span());
  }
  s->batch = control::PixelBatch(a, max_payload);
  s->scratch = a.create<core::ShadingScratch>("its tracing scratch");
  s->cost_model = cost_model;
  s->pager = a.create<Pager>("its pager", ctx, layout, cache_frames);
  for (std::uint32_t p = ctx.id(); p < layout.pages; p += ctx.node_count())
    std::memcpy(s->pager->home_frame(p), in.image->page(p).data(), layout.page_size);
  return s;
}

/// A node's side of the frame: the work farm over its submap, each pixel
/// traced through its pager (PagedView, or BrickedPagedView for a bricked
/// directory), the pages each pixel touched in `pages_channel` (when >= 0),
/// and the pager serving the page requests of other nodes between items.
void run_node(NodeContext& ctx, NodeState& s, const control::PixelLayout& pixel_layout, int pages_channel,
              int item_w, int item_h) {
  Pager& pager = *s.pager;
  const core::ShadingContext shading = core::make_shading_context(
      std::span<const core::Light>(s.lights.span()), s.background, s.render.max_depth, s.render.min_weight,
        s.render.shadow_rays);
  ctx.set_work_meter(&NodeState::work_seconds, &s);
  const control::PixelJob job{shading, s.camera, s.render.spp, s.render.any_aov(), pixel_layout, *s.scratch, s.batch};
  // The pages each pixel touched (--aov pages), and the pager's end of a work item.
  struct Hooks {
    Pager& pager;
    int pages_channel;
    void begin_pixel() { pager.begin_pixel(); }
    void after_pixel(float* o) {
      if (pages_channel >= 0) o[pages_channel] = float(pager.pixel_pages());
    }
    void end_item() { pager.end_pixel(); }
  };
  const control::OtherMessageHandler serve = [&](NodeContext&, const nodes::Message& msg) { return pager.serve(msg); };
  auto farm = [&](const auto& view) {
    return control::render_items(ctx, s.submap, item_w, item_h, view, job, Hooks{pager, pages_channel}, serve);
  };
  s.work = pager.layout().directory_order == DirectoryOrder::kBricked
               ? farm(BrickedPagedView(pager, s.grid, s.materials.span(), s.cell_order))
               : farm(PagedView(pager, s.grid, s.materials.span()));
  s.stats = s.scratch->stats;
  s.stats.traversal = s.scratch->traversal.stats;
  s.pager_stats = pager.stats();
}

}  // namespace

SvmResult render_svm(const core::Database& db, const core::Grid& grid, const SvmParams& params) {
  const core::RenderParams& rp = params.render;
  const control::ImageFrame frame = control::image_frame(db, rp, params.item_w, params.item_h);
  if (!(params.cache_fraction >= 0 && params.cache_fraction <= 1))
    throw std::invalid_argument(fmt::format("cache fraction must be in (0, 1], got {}", params.cache_fraction));

  // The host lays the database out in pages. From here on the run sees only
  // the image and the O(1) metadata (RunInput), never `db` or `grid` (the
  // host's submap estimate below reads them before the run starts).
  // With --pack-cells, the packed cells' triangle blocks are paged too.
  const DirectoryOrder order = params.directory_order.value_or(
      params.machine.nodes > 1 ? DirectoryOrder::kBricked : DirectoryOrder::kLinear);
  PagedImage image = page_database(db, grid, params, order);
  const RunInput in{&image, grid.info, db.materials, db.lights, db.background, frame.camera};
  const PageLayout& layout = image.layout;

  control::PixelLayout pixel_layout(rp);
  const int pages_channel = params.pages_aov ? pixel_layout.add_channel() : -1;
  const std::uint32_t item_bytes = control::pixels_payload_bytes(params.item_w, params.item_h, pixel_layout.channels);
  nodes::MachineParams mp = params.machine;
  mp.max_payload = std::max({mp.max_payload, item_bytes, std::uint32_t(sizeof(PageReplyMsg) + layout.page_size)});
  nodes::Machine machine(mp);  // validates the node count
  const nodes::MachineParams& m = machine.params();

  SvmResult out;
  out.layout = layout;
  // The host's work before the run: the submaps (balanced: after tracing
  // its estimate over `db` and `grid`, outside virtual time).
  out.submaps = control::plan_submaps(db, grid, in.camera, rp, m.nodes, params.submaps, m.cost_model);
  const std::vector<Rect>& submaps = out.submaps.rects;
  out.node_fixed_bytes = node_fixed_bytes(m, layout, in, submaps, params);
  // Fail before starting, with the sizes, when a node cannot hold its part.
  std::vector<std::uint32_t> cache(m.nodes);
  SvmParams sized = params;
  sized.machine = m;
  for (std::uint32_t i = 0; i < m.nodes; ++i) cache[i] = cache_frames_for(layout, sized, i, out.node_fixed_bytes);

  std::vector<core::Image*> extra;
  if (params.node_aov) extra.push_back(&out.node);
  if (params.pages_aov) extra.push_back(&out.pages);
  control::size_images(out.render, rp, frame, extra);

  std::vector<std::unique_ptr<NodeState>> states(m.nodes);
  HostPages& host_pages = image.pages;

  // The load phase (outside virtual time): each node gets its home pages
  // and the metadata; after the last node the host's image is protected.
  // The model clock's unit costs; a network that prices a fault's own work
  // (ipsc2: NetworkModel::fault_s) or an access to a cached page
  // (NetworkModel::cache_access_s) replaces the cost model's figure.
  core::CostModel cost_model = m.cost_model;
  if (m.network.fault_s >= 0) cost_model.unit_s[std::size_t(core::CostFeature::kPageFault)] = m.network.fault_s;
  if (m.network.cache_access_s >= 0)
    cost_model.unit_s[std::size_t(core::CostFeature::kCachePageAccess)] = m.network.cache_access_s;
  if (params.fetch_by_get && !(m.transport && m.transport->reads_remote()))
    throw std::invalid_argument("--page-fetch get reads home pages one-sidedly: it needs a transport with "
                                "one-sided reads (--transport mpi)");
  auto setup = [&](NodeContext& ctx) {
    states[ctx.id()] = make_node_state(ctx, in, rp, submaps[ctx.id()], cost_model, cache[ctx.id()], m.max_payload);
    if (params.fetch_by_get && m.nodes > 1) {  // collective: every process's node exposes its home frames
      states[ctx.id()]->pager->fetch_by_get(m.transport);
      m.transport->expose(states[ctx.id()]->pager->home_region());
    }
    // The last node built here: one per process under a transport.
    if (ctx.id() + 1 == m.nodes || m.transport) host_pages.protect();
  };

  auto node_main = [&](NodeContext& ctx) {
    if (params.debug_read_host_image && ctx.id() == 0) {
      volatile const std::byte* cheat = in.image->pages.data();
      (void)*cheat;  // must fault: the image is protected
    }
    run_node(ctx, *states[ctx.id()], pixel_layout, pages_channel, params.item_w, params.item_h);
  };

  auto host_main = [&](NodeContext& host) {
    const control::ExtraChannel pages[] = {{pages_channel, &out.pages}};
    control::assemble_pixels(host, pixel_layout, out.render, out.node, rp.progress,
                           std::span<const control::ExtraChannel>(pages, pages_channel >= 0 ? 1 : 0));
  };

  out.tracing.resize(m.nodes);
  out.work.resize(m.nodes);
  out.pager.resize(m.nodes);
  try {
    out.run = machine.run(node_main, host_main, setup, [&](NodeContext& ctx) {
      // Collective, so not on the way out of a failure (the job is aborted then).
      if (params.fetch_by_get && m.nodes > 1 && std::uncaught_exceptions() == 0) m.transport->conceal();
      if (states[ctx.id()]) {  // keep the counters, free the arena's contents
        out.tracing[ctx.id()] = states[ctx.id()]->stats;
        out.work[ctx.id()] = states[ctx.id()]->work;
        out.pager[ctx.id()] = states[ctx.id()]->pager_stats;
      }
      states[ctx.id()].reset();
    });
  } catch (...) {
    host_pages.unprotect();
    throw;
  }
  host_pages.unprotect();
  machine.gather(out.tracing);  // another process's nodes' counters (a transport), to the host's
  machine.gather(out.work);
  machine.gather(out.pager);
  for (const core::RenderStats& s : out.tracing) out.render.stats += s;
  return out;
}

nlohmann::json SvmResult::to_json() const {
  const PagerStats t = pager_total();
  const double tp = run.parallel_time_s;
  auto page_bytes = [](const nodes::NodeCounters& c) {
    return c.received[std::size_t(nodes::MessageType::kPageReply)].bytes;
  };
  auto node_json = [&](const PagerStats& p, const nodes::NodeCounters& c) {
    nlohmann::json by_segment;
    for (std::size_t s = 0; s < kSegments; ++s) by_segment[segment_name(Segment(s))] = p.segment_misses[s];
    return nlohmann::json{{"home_pages", p.home_pages},
                          {"cache_pages", p.cache_pages},
                          {"accesses", p.accesses},
                          {"hits", p.hits()},
                          {"misses", p.misses},
                          {"misses_by_segment", by_segment},
                          {"miss_ratio", p.miss_ratio()},
                          {"cache_accesses", p.cache_accesses},
                          {"cache_page_accesses", p.cache_page_accesses},
                          {"cache_misses", p.cache_misses},
                          {"cache_miss_ratio", p.cache_miss_ratio()},
                          {"lru_updates", p.lru_updates()},
                          {"evictions", p.evictions},
                          {"page_requests", c.sent[std::size_t(nodes::MessageType::kPageRequest)].messages},
                          {"page_requests_served", p.requests_served},
                          {"page_bytes_received", page_bytes(c)},
                          {"pixels", p.pixels},
                          {"pages_per_pixel", p.pages_per_pixel()},
                          {"pixel_pages_max", p.pixel_pages_max}};
  };
  nodes::NodeCounters total;
  for (const nodes::NodeReport& n : run.nodes) total += n.counters;
  nlohmann::json j = node_json(t, total);
  j["database_bytes"] = layout.object_bytes;
  j["shared_memory_bytes"] = layout.bytes();
  j["page_size"] = layout.page_size;
  j["pages_total"] = layout.pages;
  j["pages"] = {{"directory", layout.directory_pages},
                {"sub-grids", layout.sub_grid_pages},
                {"lists", layout.list_pages},
                {"primitives", layout.primitive_pages},
                {"normals", layout.normals_pages},
                {"blocks", layout.block_pages}};
  j["sub_grids"] = layout.sub_grids;  // paged sub-grid records (0: the grid is walked as one level)
  j["directory_order"] = directory_order_name(layout.directory_order);
  if (layout.directory_order == DirectoryOrder::kBricked)
    j["directory_brick"] = {layout.bricks.dims[0], layout.bricks.dims[1], layout.bricks.dims[2]};
  j["primitive_order"] = primitive_order_name(layout.primitive_order);
  j["pack_cells"] = layout.pack_min;
  j["packed_cells"] = layout.packed_cells;
  j["packed_blocks"] = layout.blocks;
  j["node_fixed_bytes"] = node_fixed_bytes;
  j["communication_rate_bytes_per_s"] = tp > 0 ? double(page_bytes(total)) / tp : 0.0;
  nlohmann::json per = nlohmann::json::array();
  for (std::size_t i = 0; i < pager.size() && i < run.nodes.size(); ++i) {
    nlohmann::json e = node_json(pager[i], run.nodes[i].counters);
    const double ti = run.nodes[i].work_done_s > 0 ? run.nodes[i].work_done_s : run.nodes[i].clock_s;
    e["communication_rate_bytes_per_s"] = ti > 0 ? double(page_bytes(run.nodes[i].counters)) / ti : 0.0;
    per.push_back(std::move(e));
  }
  j["per_node"] = std::move(per);
  return j;
}

}  // namespace raynode::svm
