// A node's side of the shared virtual memory: its page table, its home
// pages, an LRU page cache and the page-fault protocol (paper,
// "Distributing data"; docs/architecture.md, "svm").
//
// Place in the data flow: svm's setup builds one Pager per node in the
// node's arena and copies the node's home pages into it; PagedView
// (paged_view.h) turns every object access of the one tracer into
// at(address), an address in the shared virtual memory (page number
// above the page's bits, the byte in the page below them); a page that is
// neither home nor cached is a page fault:
// the pager sends a page request to the page's home node and waits for the
// reply, serving other nodes' page requests meanwhile and setting every
// other message aside for the work loop (no deadlock: page service never
// waits for anything). The victim frame is the least recently used cache
// page, where a page's recency is that of its first access in each pixel
// (within one pixel, pages rank by first rather than last access): every
// cache frame carries the LRU stamp of its page's last such touch, and
// every stamp given is queued; the victim is the oldest queued stamp that
// is still its frame's (O(1) amortised, "at no extra cost" as in the
// paper). The stamps are given lazily, from a list of the pixel's first
// touches, at the pixel's end or before a victim is chosen, which keeps
// the traversal's hot path a page-table read. No order is kept while the
// cache has free frames, as no victim is needed: cached pages are then
// read like home pages, and the order is built once, from the pages'
// pixel stamps, when the last free frame is taken (order_lru). A page's
// entry carries the stamp of the last pixel that touched it, so a new
// pixel starts by advancing one counter, with no pass over the pages
// touched.
//
// Virtual time: a request departs at the faulting node's clock; the home
// node answers at interrupt level, at the request's arrival plus the
// network's service cost, charged to the home node; the faulting node's
// clock becomes the reply's arrival, the gap booked as communication time.
// While it waits it gives its run permit back (nodes/scheduler.h).
//
// Memory (all in the node's arena): the page table (8 bytes per page of the
// whole database), the home pages, the cache frames, 24 bytes per cache
// frame (its page, its LRU stamp, two queued stamp events) and the list of
// the current pixel's first touches of non-home pages (1 KiB). A node's frames (home pages,
// cache, list buffer) lie within 4 GiB: the page table holds 32-bit offsets
// (each entry's word is its frame's offset minus the page's address,
// modulo 2^32, so that word + address is the byte's offset).
//
// Thread safety: owner node thread only (setup runs on the host's thread
// before the node starts).
#pragma once

#include <algorithm>
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
  /// Accesses (every one, not only a pixel's first) to pages held in cache
  /// frames, i.e. not home: what a software shared virtual memory pays its
  /// cache lookup and LRU recency update on (NetworkModel::cache_access_s).
  std::uint64_t cache_page_accesses = 0;
  /// First accesses in a pixel to pages that are not home (each an LRU
  /// update), + refaults, counted while the LRU order is kept, i.e. from
  /// the moment the cache is full: before that, cached pages are read like
  /// home pages (no order is needed while frames are free) and only their
  /// faults are seen.
  std::uint64_t cache_accesses = 0;
  std::uint64_t cache_misses = 0;    ///< faults counted in cache_accesses (while the LRU order is kept)
  std::uint64_t lru_order_frames = 0;  ///< frames stamped when the LRU order was built (order_lru)
  std::uint64_t misses = 0;          ///< page faults: pages fetched from their home node
  std::uint64_t segment_misses[kSegments] = {};  ///< misses by the segment of the page (Segment)
  std::uint64_t evictions = 0;       ///< cached pages dropped to make room (LRU)
  std::uint64_t requests_served = 0; ///< other nodes' page requests answered
  std::uint64_t pixels = 0;          ///< pixels begun (begin_pixel)
  std::uint64_t pixel_pages = 0;     ///< distinct pages touched, summed over the pixels
  std::uint32_t pixel_pages_max = 0; ///< most distinct pages one pixel touched
  std::uint32_t home_pages = 0;      ///< pages this node is home of
  std::uint32_t cache_pages = 0;     ///< cache frames

  std::uint64_t hits() const { return accesses - misses; }
  /// LRU stamps given: cache accesses + frames ordered when the cache filled.
  std::uint64_t lru_updates() const { return cache_accesses + lru_order_frames; }
  /// The full cache's own miss ratio, 0..1: faults per cache access (each
  /// non-home page once per pixel), from the moment the cache is full; 0 if
  /// it never was.
  double cache_miss_ratio() const { return cache_accesses ? double(cache_misses) / double(cache_accesses) : 0.0; }
  /// Faults per access, 0..1 (0 with no access).
  double miss_ratio() const { return accesses ? double(misses) / double(accesses) : 0.0; }
  /// The paper's "average pages per pixel" (Table 2).
  double pages_per_pixel() const { return pixels ? double(pixel_pages) / double(pixels) : 0.0; }
  PagerStats& operator+=(const PagerStats& o);
};


/// Length of a pager's touched list: first touches of non-home pages noted
/// before their LRU update.
inline constexpr std::uint32_t kPagerTouchedCapacity = 256;

/// Most bytes of one node's frames (home pages, cache, list buffer): the
/// page table holds 32-bit frame offsets.
inline constexpr std::uint64_t kPagerMaxFrameBytes = std::uint64_t(1) << 32;

/// Arena bytes a pager keeps per cache frame besides the frame: its page,
/// its LRU stamp and two queued stamp events.
inline constexpr std::size_t kPagerFrameOverheadBytes = 24;

/// Arena bytes a pager needs besides its frames: page table, LRU stamps,
/// touched list and list buffer.
std::size_t pager_table_bytes(const PageLayout& layout, std::uint32_t cache_pages);

class Pager {
 public:
  /// Takes the page table, the node's home frames and `cache_pages` cache
  /// frames from ctx's arena (throws nodes::ArenaExhausted;
  /// std::length_error when the frames, with the list buffer, exceed
  /// kPagerMaxFrameBytes). The home frames are zero until load_home_page().
  Pager(nodes::NodeContext& ctx, const PageLayout& layout, std::uint32_t cache_pages);
  /// Fetch pages with one-sided reads of the home node's home frames
  /// (`transport`'s read(), --page-fetch get) instead of a request the home
  /// node answers. Every node's home frames must be exposed (home_region()).
  void fetch_by_get(nodes::Transport* transport) { get_from_ = transport; }
  /// This node's home frames (page p at (p / nodes) x page size), for
  /// Transport::expose.
  std::span<const std::byte> home_region() const {
    return {frames_, std::size_t(home_frames_) << layout_.page_shift};
  }
  Pager(const Pager&) = delete;
  Pager& operator=(const Pager&) = delete;

  /// Setup: the frame of home page `page`, to copy its bytes into.
  /// Throws std::logic_error if this node is not its home.
  std::byte* home_frame(std::uint32_t page);

  /// The bytes of `page` (page_size of them, 64-byte aligned), valid until
  /// the page is evicted (home pages never are): at(page's first byte).
  const std::byte* access(std::uint32_t page) { return at(std::uint64_t(page) << layout_.page_shift); }

  /// The byte at shared-virtual-memory address `address` (page
  /// address >> page_shift, byte address & (page_size - 1) in it), valid
  /// until its page is evicted (home pages never are). Faults when the page
  /// is not resident. Every call counts as an access and marks the page
  /// touched in the current pixel (distinct pages per pixel).
  ///
  /// The hot path, the same for one node as for 64, is one page-table
  /// entry. Its word plus the address, modulo 2^32, is the byte's offset
  /// from the frames (the word is the frame's offset minus the page's
  /// address), so the offset in the page needs no masking. Its one branch
  /// is "not home and not touched in this pixel" (its stamp is not the
  /// pixel's; while the cache has free frames, "not resident"): touch()
  /// then notes the cache page's first touch in a short list, faults when
  /// the page is not resident (or was evicted in this pixel), and stamps
  /// the entry. Otherwise the entry takes the pixel's
  /// stamp and a home page's first touch is counted without a branch: that
  /// branch would follow the pixel's path through the scene and be
  /// mispredicted often (docs/architecture.md, "svm"). The list
  /// updates the pages' LRU recency at the pixel's end or at the next
  /// fault (flush_recency), before any victim is chosen, so evictions are
  /// those of an LRU updated at each first touch. While the cache has free
  /// frames no order is kept and a cached page takes the home pages' path
  /// (its entry's stamp is its recency; order_lru reads them when the last
  /// free frame is taken). A new pixel needs no pass over the touched
  /// pages: it only advances the stamp. Throws what the messaging throws
  /// (nodes::RunAborted) and std::logic_error on a protocol error.
  const std::byte* at(std::uint64_t address) {
    ++stats_.accesses;
    const std::uint64_t page = address >> layout_.page_shift;  // < layout_.pages
    PageEntry& e = table_.data()[page];
    std::uint32_t offset = e.word + std::uint32_t(address);
    const std::uint32_t stamp = pixel_stamp_;
    if (offset >= lookup_end_ && e.stamp != stamp) [[unlikely]] {
      // Not resident, or (once the LRU order is kept) a cache page not
      // touched in this pixel: a cache page's first touch, a fault, or a
      // touch after an eviction.
      offset = touch(std::uint32_t(page)) + (std::uint32_t(address) & (layout_.page_size - 1));
    } else {
      // Home (or cached, while no LRU order is kept), or touched in this
      // pixel. Here e.stamp <= stamp (such a page's stamp never carries
      // kEvictedInPixel, a cache page's is the pixel's), so `<` is "first
      // touch".
      pixel_pages_ += std::uint32_t(e.stamp < stamp);
      e.stamp = stamp;
    }
    stats_.cache_page_accesses += offset >= home_end_;  // a cache frame (branch-free)
    return frames_ + offset;
  }
  /// True if `p` (from at() or access()) lies in a cache frame, which a later
  /// access may evict; home pages never move.
  bool in_cache(const void* p) const { return static_cast<const std::byte*>(p) >= cache_base_; }
  /// A page-sized buffer of the node's (in its arena), for copying a list
  /// piece out of a cache frame while its ids are visited.
  std::uint32_t* list_buffer() const { return list_buffer_; }

  /// Starts a pixel: ends the previous pixel's count of distinct pages
  /// (folding it into the counters) and answers page requests that wait.
  void begin_pixel() {
    end_pixel();
    next_pixel_stamp();
    pixel_pages_ = 0;
    in_pixel_ = true;
    // Interrupt level: answer page requests that came in while we computed
    // (one acquire load when there is no mail).
    if (ctx_.has_mail()) [[unlikely]] serve_waiting();
  }
  /// Ends the current pixel's count (as begin_pixel does, without serving).
  void end_pixel() {
    if (touched_n_ > 0) flush_recency();
    if (!in_pixel_) return;
    next_pixel_stamp();  // touches until the next pixel count for nobody
    ++stats_.pixels;
    stats_.pixel_pages += pixel_pages_;
    stats_.pixel_pages_max = std::max(stats_.pixel_pages_max, pixel_pages_);
    in_pixel_ = false;
  }
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
  bool resident(std::uint32_t page) const { return frame_offset(page) != not_resident_; }
  /// Is the LRU order kept (the cache has been full, or keep_lru_order)?
  /// (With no cache frames, from the start: there is nothing to order.)
  bool lru_ordered() const { return lookup_end_ == home_end_; }
  /// Keeps the LRU order from now on, free frames or not (for `bench
  /// cost-model`, which measures the cost of an LRU update).
  void keep_lru_order() {
    if (!lru_ordered()) order_lru(kNone);
  }

 private:
  /// PageEntry::stamp's top bit: the page was touched in the pixel whose
  /// stamp the other bits hold, then evicted (counted, off the fast path).
  static constexpr std::uint32_t kEvictedInPixel = 0x80000000u;
  static constexpr std::uint32_t kNone = 0xffffffffu;
  /// First touches of non-home pages noted before the LRU is updated.
  static constexpr std::uint32_t kTouchedCapacity = kPagerTouchedCapacity;
  struct PageEntry {
    /// The page's frame offset from frames_ (a multiple of 64) minus the
    /// page's address (page << page_shift), modulo 2^32; a page that is not
    /// resident has the frame offset not_resident_.
    std::uint32_t word = 0;
    /// Stamp of the pixel of its last first touch (0: never touched; the
    /// current pixel's: resident and touched in this pixel, at()'s fast
    /// path), | kEvictedInPixel when evicted since.
    std::uint32_t stamp = 0;
  };
  struct alignas(64) Line {
    std::byte bytes[64];
  };
  /// A stamp given to a cache frame, in stamp order in a ring buffer.
  /// Stamps are compared for equality only: a stale event is dropped within
  /// one ring's length of stamps, so 32 bits cannot wrap onto it.
  struct LruEvent {
    std::uint32_t frame;  ///< index among the cache frames
    std::uint32_t stamp;
  };

  /// at()'s other path: the first touch in this pixel of a page that is
  /// not home (or its touch after an eviction in this pixel, or a fault);
  /// returns the page's frame offset.
  [[gnu::noinline]] std::uint32_t touch(std::uint32_t page);
  /// Gives every page in the touched list a new LRU stamp, in first-touch
  /// order, and counts them as LRU updates.
  [[gnu::noinline]] void flush_recency();
  /// Starts keeping the LRU order: stamps the occupied cache frames in the
  /// order of their pages' pixel stamps (the last pixel that touched each;
  /// within one pixel, by frame, i.e. fetch order), frame `newest` (a cache
  /// frame index, or kNone) last, and sends cache pages' first touches
  /// in a pixel back through touch(). O(F log F) for F occupied frames,
  /// once per run; counts F in lru_order_frames.
  [[gnu::noinline]] void order_lru(std::uint32_t newest);
  /// Advances the pixel stamp (every entry leaves the fast path); on
  /// wrapping, forgets every entry's stamp.
  void next_pixel_stamp() {
    if (++pixel_stamp_ == kEvictedInPixel) [[unlikely]] forget_stamps();
  }
  /// On the stamp's wrapping: every entry's stamp back to 0, the pixel's to 1.
  [[gnu::noinline]] void forget_stamps();
  /// Answers the page requests that wait; defers other messages.
  [[gnu::noinline]] void serve_waiting();
  /// The frame offset of `page` (not_resident_ when it is not resident).
  std::uint32_t frame_offset(std::uint32_t page) const { return table_[page].word + (page << layout_.page_shift); }
  /// Makes `page`'s frame offset `offset`.
  void set_frame_offset(std::uint32_t page, std::uint32_t offset) {
    table_[page].word = offset - (page << layout_.page_shift);
  }
  /// Gives cache frame `f` (index among the cache frames) a new LRU stamp.
  void stamp(std::uint32_t f) {
    frame_used_[f] = ++lru_clock_;
    if (events_n_ == events_.size()) compact_events();
    std::size_t at = events_head_ + events_n_;
    if (at >= events_.size()) at -= events_.size();
    events_[at] = LruEvent{f, lru_clock_};
    ++events_n_;
  }
  /// Drops the stamp events that a later stamp of their frame replaced.
  void compact_events();
  /// The cache frame whose page was least recently used: the oldest event
  /// that is still its frame's stamp. O(1) amortised (each event is
  /// dropped once).
  std::uint32_t lru_victim();
  /// Fetches `page` from its home node into a cache frame; returns the
  /// frame's offset.
  [[gnu::noinline]] std::uint32_t fault(std::uint32_t page);
  /// Answers waiting page requests; defers other messages.
  void serve_or_defer(const nodes::Message& m);
  /// fault()'s wait for the home node's reply: the page's arrival time.
  double await_page(std::uint32_t page, nodes::NodeId home, std::byte* frame, bool& released, nodes::Message& m);

  // at()'s fields first, near each other (the counters last of them, so
  // that their size does not push the others apart).
  nodes::ArenaArray<PageEntry> table_;
  std::byte* frames_ = nullptr;
  /// Advances at each pixel's start and end, below kEvictedInPixel; 0 = never.
  std::uint32_t pixel_stamp_ = 1;
  /// Offsets below it take at()'s fast path: home_end_ once the LRU order
  /// is kept (order_lru), else not_resident_ (every resident page).
  std::uint32_t lookup_end_ = 0;
  std::uint32_t home_end_ = 0;  ///< byte offset of the first cache frame: offsets below it are home pages
  std::uint32_t pixel_pages_ = 0;
  PagerStats stats_;
  PageLayout layout_;

  nodes::NodeContext& ctx_;
  std::uint32_t nodes_;
  std::uint32_t home_frames_;
  /// The frame offset of a page that is not resident: the list buffer's,
  /// never a page's frame (an offset in it stays at or above home_end_).
  std::uint32_t not_resident_ = 0;
  std::uint32_t cache_frames_;
  nodes::Transport* get_from_ = nullptr;  ///< fetch_by_get(): one-sided page reads
  std::uint32_t cache_used_ = 0;
  nodes::ArenaArray<std::uint32_t> frame_page_;  ///< per cache frame: its page, or kNone
  nodes::ArenaArray<std::uint32_t> frame_used_;  ///< per cache frame: LRU stamp of its last (first-per-pixel) touch
  nodes::ArenaArray<LruEvent> events_;           ///< ring of stamp events, oldest first (2 per cache frame)
  std::size_t events_head_ = 0, events_n_ = 0;
  nodes::ArenaArray<std::uint32_t> touched_;     ///< kTouchedCapacity slots
  /// The frames: home pages, cache frames, the list buffer. Uninitialised
  /// (nodes::kUninitialized): each is written before it is read (a home
  /// page by the load, a cache frame by its fetch, the buffer by its list),
  /// so cache frames that no fault fills cost the host no memory.
  nodes::ArenaArray<Line> lines_;
  const std::byte* cache_base_ = nullptr;  ///< first cache frame
  std::uint32_t* list_buffer_ = nullptr;   ///< one page after the cache frames
  std::uint32_t touched_n_ = 0;
  std::uint32_t lru_clock_ = 0;  ///< last LRU stamp given
  bool in_pixel_ = false;
};

}  // namespace raynode::svm
