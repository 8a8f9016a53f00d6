// `--mode svm`: the paper's control-oriented algorithm (section "Shared
// virtual memory", Tables 2 and 3, Figures 5-10). Every node runs the
// sequential tracer over the whole database, which lives in a read-only
// shared virtual memory of fixed-size pages spread over all nodes' memories:
// each node keeps its home pages and caches others' pages it reads (LRU);
// pixels are distributed as square submaps (or, --submaps balanced, parts
// of near-equal estimated cost: control/submap_plan.h) plus 3x3 work items
// stolen along the ring (control/work.h).
//
// Place in the data flow: host Database + Grid -> build_paged_image
// (paged_database.h) -> setup: each node's arena gets its page table, home
// pages, cache frames and the replicated metadata (grid description,
// materials, lights, camera) -> the host's image is protected (mprotect)
// -> node: PagedView over its Pager -> core::render_pixel per pixel ->
// kPixels messages -> host frame buffer. The arithmetic is the sequential
// tracer's on the same bytes, so the image is bit-identical to
// `--mode sequential` for every node count and cache size.
#pragma once

#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <vector>

#include "core/database.h"
#include "core/grid.h"
#include "core/render.h"
#include "nodes/machine.h"
#include "control/submap_plan.h"
#include "control/work.h"
#include "svm/pager.h"
#include "svm/paged_database.h"

namespace raynode::svm {

struct SvmParams {
  core::RenderParams render;      ///< resolution, spp, depth, AOVs (mode and tile size ignored)
  nodes::MachineParams machine;   ///< nodes, memory, network, topology (payload sized automatically)
  std::int32_t item_w = 3;        ///< work item, pixels (--work-item WxH)
  std::int32_t item_h = 3;
  std::uint32_t page_size = 1024; ///< bytes (--page-size), a power of two >= 64
  /// Cells listing at least this many triangles are paged as triangle
  /// blocks (--pack-cells N, core/cell_blocks.h; needs pages of 512 B or
  /// more); 0 = off, the paper's object lists only.
  std::uint32_t pack_min = 0;
  /// The cell directory's order (--directory-order); nullopt = auto:
  /// bricked when the machine has more than one node (it halves the
  /// directory pages a node fetches; on one node, where every page is home,
  /// the linear order's walk is cheaper).
  std::optional<DirectoryOrder> directory_order;
  /// The primitive records' order in their pages (--primitive-order);
  /// nullopt = auto: with the adaptive grid the order whose cell lists
  /// name fewer pages, cells weighted by their surface (fewer_list_pages),
  /// with the paper's uniform grid the database's (file) order, the
  /// paper's layout.
  std::optional<PrimitiveOrder> primitive_order;
  /// Cache frames per node (--cache N): 0 = all the room the node's memory
  /// has left after its home pages, page table, mailbox and buffers.
  std::uint32_t cache_pages = 0;
  /// Cache as a fraction of the database's pages (--cache P%), used when > 0.
  double cache_fraction = 0;
  /// The static submaps (--submaps, --subsample): square (the paper's)
  /// or balanced by a host estimate (control/submap_plan.h).
  control::SubmapParams submaps;
  /// Fetch a page with a one-sided read of its home node's frame
  /// (Transport::read, --page-fetch get) instead of a request the home node
  /// answers. Needs a transport with one-sided reads (std::invalid_argument).
  bool fetch_by_get = false;
  bool node_aov = false;   ///< image of which node computed each pixel (the paper's Figure 6)
  bool pages_aov = false;  ///< image of the distinct pages each pixel touched
  /// Test of the no-cheating rule: node 0 reads the host's (protected)
  /// page image during the run, which must kill the process (SIGSEGV).
  bool debug_read_host_image = false;
};

struct SvmResult {
  core::RenderResult render;               ///< image, AOVs, counters summed over the nodes
  core::Image node;                        ///< 1 channel: node that computed each pixel (node_aov)
  core::Image pages;                       ///< 1 channel: distinct pages touched per pixel (pages_aov)
  nodes::RunReport run;                    ///< machine counters and virtual times
  std::vector<control::WorkStats> work;      ///< per node
  std::vector<core::RenderStats> tracing;  ///< per node
  std::vector<PagerStats> pager;           ///< per node
  PageLayout layout;                       ///< the shared virtual memory's layout
  std::size_t node_fixed_bytes = 0;        ///< per node: page table, mailbox, buffers, metadata
  control::SubmapPlan submaps;               ///< the nodes' submaps and, if balanced, the estimate's cost

  /// Pager counters summed over the nodes.
  PagerStats pager_total() const;
  /// The "svm" object of --stats: database_bytes, pages_total, page_size,
  /// cache pages, hits, misses, miss_ratio, evictions, page requests and
  /// bytes, pages_per_pixel, communication rate (bytes per virtual second),
  /// and "per_node" (the same per node).
  nlohmann::json to_json() const;
};

/// Cache frames node `node` gets (see SvmParams::cache_pages), or throws
/// std::runtime_error naming the sizes when the node cannot hold its home
/// pages and the cache it needs. `fixed` = its other arena bytes.
std::uint32_t cache_frames_for(const PageLayout& layout, const SvmParams& params, std::uint32_t node,
                               std::size_t fixed);

/// Renders `db` in svm mode. Throws std::runtime_error before starting when
/// the database does not fit ("svm mode: the database needs X, N nodes x M
/// hold Y ...") or a requested cache does not fit; std::invalid_argument
/// for bad parameters (page size, work item, spp); nodes::NodeError for
/// failures inside the run.
SvmResult render_svm(const core::Database& db, const core::Grid& grid, const SvmParams& params);

}  // namespace raynode::svm
