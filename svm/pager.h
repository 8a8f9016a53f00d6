// A node's side of the shared virtual memory: its page table, its home
// pages, an LRU page cache and the page-fault protocol (paper,
// "Distributing data"; DESIGN.md, "svm").
//
// Place in the data flow: svm's setup builds one Pager per node in the
// node's arena and copies the node's home pages into it; PagedView
// (paged_view.h) turns every object access of the one tracer into
// access(page); a page that is neither home nor cached is a page fault:
// the pager sends a page request to the page's home node and waits for the
// reply, serving other nodes' page requests meanwhile and setting every
// other message aside for the work loop (no deadlock: page service never
// waits for anything). The victim frame is the least recently used cache
// page ("LRU ... at no extra cost" in the paper: the choice is O(1)), where
// a page's recency is that of its first access in each pixel: the LRU list
// is updated when a pixel first touches a page (through the page table),
// not on the pixel's later accesses to it (through the TLB), which keeps
// the traversal's hot path free of list updates. Within one pixel, pages
// therefore rank by first rather than last access.
//
// Virtual time: a request departs at the faulting node's clock; the home
// node answers at interrupt level, at the request's arrival plus the
// network's service cost, charged to the home node; the faulting node's
// clock becomes the reply's arrival, the gap booked as communication time.
// While it waits it gives its run permit back (nodes/scheduler.h).
//
// Memory (all in the node's arena): the page table (8 bytes per page of the
// whole database), the home pages, the cache frames and 12 bytes of LRU
// links per cache frame.
//
// Thread safety: owner node thread only (setup runs on the host's thread
// before the node starts).
#pragma once

#include <cstdint>

#include "nodes/node.h"
#include "svm/paged_database.h"

namespace raynode::svm {

/// Messages of the pager protocol (wire size = sizeof, + the page).
struct PageRequestMsg {
  std::uint32_t page;
};
/// Header of a kPageReply message; followed by the page's bytes.
struct PageReplyMsg {
  std::uint32_t page;
};

/// Counters of one node's pager.
struct PagerStats {
  std::uint64_t accesses = 0;        ///< object accesses through the page table
  std::uint64_t cache_accesses = 0;  ///< page-table lookups of pages that are not home pages (first per pixel)
  std::uint64_t table_lookups = 0;   ///< accesses that went through the page table (TLB misses)
  std::uint64_t misses = 0;          ///< page faults: pages fetched from their home node
  std::uint64_t evictions = 0;       ///< cached pages dropped to make room (LRU)
  std::uint64_t requests_served = 0; ///< other nodes' page requests answered
  std::uint64_t pixels = 0;          ///< pixels begun (begin_pixel)
  std::uint64_t pixel_pages = 0;     ///< distinct pages touched, summed over the pixels
  std::uint32_t pixel_pages_max = 0; ///< most distinct pages one pixel touched
  std::uint32_t home_pages = 0;      ///< pages this node is home of
  std::uint32_t cache_pages = 0;     ///< cache frames

  std::uint64_t hits() const { return accesses - misses; }
  /// Faults per access, 0..1 (0 with no access).
  double miss_ratio() const { return accesses ? double(misses) / double(accesses) : 0.0; }
  /// Faults per page-table lookup of a non-home page: the cache's own miss
  /// ratio, counting each page once per pixel.
  double cache_miss_ratio() const { return cache_accesses ? double(misses) / double(cache_accesses) : 0.0; }
  /// The paper's "average pages per pixel" (Table 2).
  double pages_per_pixel() const { return pixels ? double(pixel_pages) / double(pixels) : 0.0; }
  PagerStats& operator+=(const PagerStats& o);
};


/// Arena bytes a pager needs besides its frames: page table and LRU links.
std::size_t pager_table_bytes(const PageLayout& layout, std::uint32_t cache_pages);

class Pager {
 public:
  /// Takes the page table, the node's home frames and `cache_pages` cache
  /// frames from ctx's arena (throws nodes::ArenaExhausted). The home
  /// frames are zero until load_home_page().
  Pager(nodes::NodeContext& ctx, const PageLayout& layout, std::uint32_t cache_pages);
  Pager(const Pager&) = delete;
  Pager& operator=(const Pager&) = delete;

  /// Setup: the frame of home page `page`, to copy its bytes into.
  /// Throws std::logic_error if this node is not its home.
  std::byte* home_frame(std::uint32_t page);

  /// The bytes of `page` (page_size of them, 64-byte aligned), valid until
  /// the page is evicted (home pages never are). Faults
  /// when it is not resident. Every call counts as an access. A page
  /// already accessed in the current pixel takes a
  /// short path: a direct-mapped translation cache (TLB) of kTlbEntries
  /// pages whose tags include the pixel's stamp, so the first access of a
  /// page in each pixel goes through the page table, which counts distinct
  /// pages per pixel, and the short path stores nothing but the access
  /// count. Throws what the messaging throws (nodes::RunAborted) and
  /// std::logic_error on a protocol error.
  ///
  /// A node that is home to every page (one node) needs no translation:
  /// page p is frame p, so the address is computed, not looked up, and
  /// only the counting touches the page table (off the address's path).
  const std::byte* access(std::uint32_t page) {
    if (all_home_) {
      // Branch-free counting (a branch on "first touch in this pixel"
      // mispredicts ~20 times per pixel and measured slower).
      PageEntry& e = table_[page];
      pixel_pages_ += std::uint32_t(e.stamp != pixel_stamp_);
      e.stamp = pixel_stamp_;
      ++stats_.accesses;
      return frames_ + (std::size_t(page) << layout_.page_shift);
    }
    const Tlb& t = tlb_[page & (kTlbEntries - 1)];
    if (t.key == (pixel_key_ | page)) [[likely]] {
      ++stats_.accesses;
      return t.data;
    }
    return lookup(page);
  }
  /// True if `p` (from access()) lies in a cache frame, which a later
  /// access may evict; home pages never move.
  bool in_cache(const void* p) const { return static_cast<const std::byte*>(p) >= cache_base_; }
  /// A page-sized buffer of the node's (in its arena), for copying a list
  /// piece out of a cache frame while its ids are visited.
  std::uint32_t* list_buffer() const { return list_buffer_; }

  /// Starts a pixel: ends the previous pixel's count of distinct pages
  /// (folding it into the counters) and answers page requests that wait.
  void begin_pixel();
  /// Ends the current pixel's count (as begin_pixel does, without serving).
  void end_pixel();
  /// Distinct pages touched since the last begin_pixel().
  std::uint32_t pixel_pages() const { return pixel_pages_; }

  /// Serves `m` if it is a page request (interrupt level: the reply leaves
  /// at its arrival + the network's service cost); returns false for any
  /// other message. Throws std::logic_error for a page this node is not
  /// home of, or a page reply nobody waits for.
  bool serve(const nodes::Message& m);

  const PageLayout& layout() const { return layout_; }
  const PagerStats& stats() const { return stats_; }
  /// Is `page` resident (home or cached)? For tests.
  bool resident(std::uint32_t page) const { return table_[page].frame != kNotResident; }

 private:
  static constexpr std::uint32_t kNotResident = 0xffffffffu;
  static constexpr std::uint32_t kNone = 0xffffffffu;
  struct PageEntry {
    std::uint32_t frame = kNotResident;  ///< frame index, or kNotResident
    std::uint32_t stamp = 0;             ///< pixel stamp of the last touch
  };
  struct LruLink {
    std::uint32_t prev = kNone, next = kNone;  ///< frame indices, towards MRU / LRU
    std::uint32_t page = kNone;                ///< page in the frame
  };
  struct alignas(64) Line {
    std::byte bytes[64];
  };

  static constexpr std::uint32_t kTlbEntries = 64;  // power of two
  struct Tlb {
    std::uint64_t key = ~std::uint64_t(0);  ///< pixel stamp << 32 | page; ~0 = empty
    const std::byte* data = nullptr;        ///< the frame
  };
  /// The page-table path of access(): counts, stamps, LRU, fault; fills `t`.
  /// Out of line (also under the tracer's [[gnu::flatten]]), so that the
  /// traversal loop keeps only the TLB check.
  [[gnu::noinline]] const std::byte* lookup(std::uint32_t page) {
    PageEntry& e = table_[page];
    if (e.stamp != pixel_stamp_) {
      e.stamp = pixel_stamp_;
      ++pixel_pages_;
    }
    ++stats_.accesses;
    ++stats_.table_lookups;
    std::uint32_t f = e.frame;
    const std::byte* data;
    if (f == kNotResident) [[unlikely]] {
      ++stats_.cache_accesses;
      data = fault(page);
      f = e.frame;
    } else {
      if (f >= home_frames_) cache_hit(f);
      data = frames_ + (std::size_t(f) << layout_.page_shift);
    }
    tlb_[page & (kTlbEntries - 1)] = Tlb{pixel_key_ | page, data};
    return data;
  }
  void cache_hit(std::uint32_t f) {
    ++stats_.cache_accesses;
    if (f != mru_) touch(f);
  }
  [[gnu::noinline]] void touch(std::uint32_t frame);
  /// Forgets `page`'s translation (it was evicted).
  void forget(std::uint32_t page) {
    Tlb& t = tlb_[page & (kTlbEntries - 1)];
    if (std::uint32_t(t.key) == page) t.key = ~std::uint64_t(0);
  }
  [[gnu::noinline]] const std::byte* fault(std::uint32_t page);
  void unlink(std::uint32_t frame);
  void push_front(std::uint32_t frame);
  LruLink& link(std::uint32_t frame) { return lru_[frame - home_frames_]; }
  /// Answers waiting page requests; defers other messages.
  void serve_or_defer(const nodes::Message& m);

  nodes::NodeContext& ctx_;
  PageLayout layout_;
  std::uint32_t nodes_;
  std::uint32_t home_frames_;
  std::uint32_t cache_frames_;
  std::uint32_t cache_used_ = 0;
  std::uint32_t mru_ = kNone, lru_tail_ = kNone;
  nodes::ArenaArray<PageEntry> table_;
  nodes::ArenaArray<LruLink> lru_;
  nodes::ArenaArray<Line> lines_;
  std::byte* frames_ = nullptr;
  const std::byte* cache_base_ = nullptr;  ///< first cache frame
  bool all_home_ = false;                  ///< home to every page: frame == page
  std::uint32_t* list_buffer_ = nullptr;   ///< one page after the cache frames
  Tlb tlb_[kTlbEntries];
  std::uint32_t pixel_stamp_ = 1;
  std::uint64_t pixel_key_ = std::uint64_t(1) << 32;  ///< pixel_stamp_ << 32, the TLB tags' high half
  std::uint32_t pixel_pages_ = 0;
  bool in_pixel_ = false;
  PagerStats stats_;
};

}  // namespace raynode::svm
