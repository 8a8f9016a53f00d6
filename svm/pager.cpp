#include "svm/pager.h"

#include <fmt/core.h>

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <thread>

namespace raynode::svm {

namespace {
/// Yields before a page fault blocks (see Pager::fault).
constexpr int kSpinYields = 64;
}  // namespace

PagerStats& PagerStats::operator+=(const PagerStats& o) {
  accesses += o.accesses;
  cache_accesses += o.cache_accesses;
  cache_page_accesses += o.cache_page_accesses;
  cache_misses += o.cache_misses;
  lru_order_frames += o.lru_order_frames;
  misses += o.misses;
  for (std::size_t s = 0; s < kSegments; ++s) segment_misses[s] += o.segment_misses[s];
  evictions += o.evictions;
  requests_served += o.requests_served;
  pixels += o.pixels;
  pixel_pages += o.pixel_pages;
  pixel_pages_max = std::max(pixel_pages_max, o.pixel_pages_max);
  home_pages += o.home_pages;
  cache_pages += o.cache_pages;
  return *this;
}

std::size_t pager_table_bytes(const PageLayout& layout, std::uint32_t cache_pages) {
  // + the list buffer, + alignment of the five arrays (64 B each at most)
  return std::size_t(layout.pages) * 8 + std::size_t(cache_pages) * kPagerFrameOverheadBytes +
         std::size_t(kPagerTouchedCapacity) * 4 + layout.page_size + 5 * 64;
}

namespace {
/// `frames` frames of `layout`'s pages, or std::length_error past
/// kPagerMaxFrameBytes.
std::uint64_t checked_frames(const PageLayout& layout, std::uint64_t frames) {
  const std::uint64_t bytes = frames * layout.page_size;
  if (bytes > kPagerMaxFrameBytes)
    throw std::length_error(fmt::format("svm: a node's frames take {} B ({} pages of {} B), more than the pager's "
                                        "limit of {} B; use more nodes or a smaller --cache",
                                        bytes, frames, layout.page_size, kPagerMaxFrameBytes));
  return frames;
}
}  // namespace

Pager::Pager(nodes::NodeContext& ctx, const PageLayout& layout, std::uint32_t cache_pages)
    : table_(ctx.arena(), layout.pages, "its page table"),
      layout_(layout),
      ctx_(ctx),
      nodes_(ctx.node_count()),
      home_frames_(layout.home_pages(ctx.id(), ctx.node_count())),
      cache_frames_(cache_pages),
      frame_page_(ctx.arena(), cache_pages, "its cache frames' pages"),
      frame_used_(ctx.arena(), cache_pages, "its LRU stamps"),
      events_(ctx.arena(), std::size_t(cache_pages) * 2, "its LRU stamp events"),
      touched_(ctx.arena(), kTouchedCapacity, "its touched-page list"),
      lines_(ctx.arena(),
             checked_frames(layout, std::uint64_t(home_frames_) + cache_pages + 1) * (layout.page_size / sizeof(Line)),
             "its home pages, page cache and list buffer", nodes::kUninitialized) {
  static_assert(sizeof(PageEntry) == 8 && sizeof(std::uint32_t) * 2 + 2 * sizeof(LruEvent) == kPagerFrameOverheadBytes &&
                    kTouchedCapacity == kPagerTouchedCapacity,
                "pager_table_bytes counts these sizes");
  for (std::uint32_t f = 0; f < cache_pages; ++f) frame_page_[f] = kNone;
  frames_ = reinterpret_cast<std::byte*>(lines_.data());
  cache_base_ = frames_ + (std::size_t(home_frames_) << layout.page_shift);
  list_buffer_ = reinterpret_cast<std::uint32_t*>(frames_ + (std::size_t(home_frames_ + cache_pages) << layout.page_shift));
  // The frames end at or below 2^32 bytes (checked_frames), the list
  // buffer last: its offset is no page's.
  not_resident_ = (home_frames_ + cache_pages) << layout.page_shift;
  for (std::uint32_t p = 0; p < layout.pages; ++p) set_frame_offset(p, not_resident_);
  for (std::uint32_t s = 0; s < home_frames_; ++s)
    set_frame_offset(s * nodes_ + ctx.id(), s << layout.page_shift);
  home_end_ = home_frames_ << layout.page_shift;
  lookup_end_ = not_resident_;  // no LRU order yet
  stats_.home_pages = home_frames_;
  stats_.cache_pages = cache_frames_;
}

std::byte* Pager::home_frame(std::uint32_t page) {
  if (page >= layout_.pages || PageLayout::home(page, nodes_) != ctx_.id())
    throw std::logic_error(fmt::format("{} is not the home of page {}", nodes::node_name(ctx_.id()), page));
  return frames_ + (std::size_t(PageLayout::home_slot(page, nodes_)) << layout_.page_shift);
}

void Pager::flush_recency() {
  for (std::uint32_t i = 0; i < touched_n_; ++i) {
    const std::uint32_t offset = frame_offset(touched_[i]);  // non-home: a cache frame or not resident
    if (offset != not_resident_) stamp((offset >> layout_.page_shift) - home_frames_);
  }
  stats_.cache_accesses += touched_n_;
  touched_n_ = 0;
}

void Pager::order_lru(std::uint32_t newest) {
  // The event ring (2 per frame) is the sort's scratch: {frame, pixel stamp}.
  const std::uint32_t n = cache_used_;
  for (std::uint32_t f = 0; f < n; ++f)
    events_[f] = LruEvent{f, f == newest ? kNone : table_[frame_page_[f]].stamp & ~kEvictedInPixel};
  std::sort(events_.data(), events_.data() + n, [](const LruEvent& a, const LruEvent& b) {
    return a.stamp != b.stamp ? a.stamp < b.stamp : a.frame < b.frame;
  });
  for (std::uint32_t i = 0; i < n; ++i) {
    frame_used_[events_[i].frame] = ++lru_clock_;
    events_[i].stamp = lru_clock_;
  }
  events_head_ = 0;
  events_n_ = n;
  stats_.lru_order_frames += n;
  lookup_end_ = home_end_;  // lru_ordered()
}

void Pager::compact_events() {
  // In place, oldest first: an event is kept while it is its frame's stamp
  // (at most one per frame, so at least half the ring comes free).
  const std::size_t size = events_.size();
  std::size_t kept = 0;
  for (std::size_t i = 0, from = events_head_; i < events_n_; ++i) {
    const LruEvent e = events_[from];
    if (frame_used_[e.frame] == e.stamp) {
      std::size_t to = events_head_ + kept;
      if (to >= size) to -= size;
      events_[to] = e;
      ++kept;
    }
    if (++from == size) from = 0;
  }
  events_n_ = kept;
}

std::uint32_t Pager::lru_victim() {
  // Every occupied frame's stamp is queued, so a full cache finds one.
  while (true) {
    const LruEvent e = events_[events_head_];
    if (++events_head_ == events_.size()) events_head_ = 0;
    --events_n_;
    if (frame_used_[e.frame] == e.stamp) return home_frames_ + e.frame;
  }
}

std::uint32_t Pager::touch(std::uint32_t page) {
  // Locals and one entry pointer: the list's stores could alias the entry.
  PageEntry* const entry = &table_[page];
  const std::uint32_t offset = frame_offset(page);
  // Touched before in this pixel, then evicted: not a new distinct page, and
  // not in the touched list a second time.
  const bool first = (entry->stamp & ~kEvictedInPixel) != pixel_stamp_;
  if (first) {
    ++pixel_pages_;
    if (offset >= home_end_ && lru_ordered()) {  // a cache frame, or not resident
      touched_[touched_n_++] = page;
      if (touched_n_ == kTouchedCapacity) [[unlikely]] flush_recency();
    }
  }
  if (offset == not_resident_) [[unlikely]] {
    if (!first) ++stats_.cache_accesses;  // counted here, as it is not in the touched list
    const std::uint32_t fetched = fault(page);  // may evict other pages
    entry->stamp = pixel_stamp_;
    return fetched;
  }
  entry->stamp = pixel_stamp_;  // on the fast path until the pixel ends or an eviction
  return offset;
}

void Pager::forget_stamps() {
  // The stamps are the recency of cached pages while no order is kept.
  if (!lru_ordered() && cache_used_ > 0) order_lru(kNone);
  for (std::size_t p = 0; p < table_.size(); ++p) table_[p].stamp = 0;
  pixel_stamp_ = 1;
}

void Pager::serve_waiting() {
  nodes::Message m;
  while (ctx_.poll(m)) serve_or_defer(m);
  ctx_.resume_deferred();
}

void Pager::serve_or_defer(const nodes::Message& m) {
  if (!serve(m)) ctx_.defer(m);
}

bool Pager::serve(const nodes::Message& m) {
  if (m.type() == nodes::MessageType::kPageReply)
    throw std::logic_error(fmt::format("{}: a page reply from {} while no page fault waits",
                                       nodes::node_name(ctx_.id()), nodes::node_name(m.source())));
  if (m.type() != nodes::MessageType::kPageRequest) return false;
  const std::uint32_t page = m.as<PageRequestMsg>().page;
  if (page >= layout_.pages || PageLayout::home(page, nodes_) != ctx_.id())
    throw std::logic_error(fmt::format("{}: {} asked for page {}, which does not live here",
                                       nodes::node_name(ctx_.id()), nodes::node_name(m.source()), page));
  const double depart = ctx_.serve_interrupt(m.header.arrival_time, ctx_.network().reply_service_s());
  const std::byte* bytes = frames_ + (std::size_t(PageLayout::home_slot(page, nodes_)) << layout_.page_shift);
  ctx_.send(m.source(), nodes::MessageType::kPageReply, PageReplyMsg{page},
            std::span<const std::byte>(bytes, layout_.page_size), depart);
  ++stats_.requests_served;
  return true;
}

/// Waits for the reply to this node's request for `page` from `home`,
/// copies it into `frame` and returns its arrival time, serving (or
/// deferring) other mail meanwhile; `released` tells whether the run permit
/// was given up.
double Pager::await_page(std::uint32_t page, nodes::NodeId home, std::byte* frame, bool& released, nodes::Message& m) {
  bool got = false;
  double arrival = 0;
  int spins = 0;
  while (!got) {
    if (!ctx_.poll(m)) {
      // The reply usually comes within microseconds (the home node serves
      // at its next poll): wait for it on this CPU first, yielding to the
      // home node's thread, so that this node's caches stay warm (its CPU
      // time is its virtual clock: refilling them after a thread switch
      // would be charged as work). The wait itself is not work: it is
      // dropped from the clock, which advance_to() in fault() sets to the
      // reply's arrival. Then block, giving the run permit away. Not while
      // the home node needs a permit to read its mail (scheduled mail
      // wake-ups): every permit may be held by nodes spinning like this
      // one, and each spin of 64 yields then ran to its end, a scheduler
      // time slice per yield on a loaded machine (a 48x40 render at 4
      // nodes took minutes).
      if (spins < kSpinYields && ctx_.compute_clock() == nodes::ComputeClock::kCpu && ctx_.peer_reads_mail(home)) {
        ++spins;
        std::this_thread::yield();
        ctx_.reset_cpu_mark();
        continue;
      }
      if (!released) {
        ctx_.await_reply();
        released = true;
      }
      ctx_.wait_for_mail(0);
      continue;
    }
    if (m.type() == nodes::MessageType::kPageReply) {
      const std::uint32_t p = m.as<PageReplyMsg>().page;
      const std::span<const std::byte> bytes = m.tail<PageReplyMsg>();
      if (p != page || m.source() != home || bytes.size() != layout_.page_size)
        throw std::logic_error(fmt::format("{}: waiting for page {} from {}, got page {} ({} B) from {}",
                                           nodes::node_name(ctx_.id()), page, nodes::node_name(home), p,
                                           bytes.size(), nodes::node_name(m.source())));
      std::memcpy(frame, bytes.data(), layout_.page_size);
      arrival = m.header.arrival_time;
      got = true;
    } else {
      serve_or_defer(m);
    }
  }
  return arrival;
}

std::uint32_t Pager::fault(std::uint32_t page) {
  if (page >= layout_.pages)
    throw std::logic_error(fmt::format("{}: access to page {} of {}", nodes::node_name(ctx_.id()), page,
                                       layout_.pages));
  if (cache_frames_ == 0)
    throw std::logic_error(fmt::format("{}: page {} is not home and the node has no cache",
                                       nodes::node_name(ctx_.id()), page));
  ++stats_.misses;
  if (lru_ordered()) ++stats_.cache_misses;
  ++stats_.segment_misses[std::size_t(layout_.segment(page))];
  // The victim: a free cache frame, else the least recently used page (the
  // touches noted so far in this pixel count).
  flush_recency();
  std::uint32_t victim;
  if (cache_used_ < cache_frames_) {
    victim = home_frames_ + cache_used_++;
  } else {
    victim = lru_victim();
    // Off at()'s fast path; its stamp remembers a touch in this pixel.
    const std::uint32_t evicted_page = frame_page_[victim - home_frames_];
    PageEntry& evicted = table_[evicted_page];
    set_frame_offset(evicted_page, not_resident_);
    if (evicted.stamp == pixel_stamp_) evicted.stamp |= kEvictedInPixel;
    frame_page_[victim - home_frames_] = kNone;
    ++stats_.evictions;
    }

  const nodes::NodeId home = PageLayout::home(page, nodes_);
  std::byte* frame = frames_ + (std::size_t(victim) << layout_.page_shift);
  double arrival = 0;
  bool released = false;
  nodes::Message m;
  if (get_from_) {
    // One-sided: read the home frame; the home node takes no part. In
    // virtual time it costs what a request and its reply would.
    const double start = ctx_.now();
    ctx_.note_wait(nodes::WaitReason::kPage, page, home);
    get_from_->read(home, std::size_t(PageLayout::home_slot(page, nodes_)) << layout_.page_shift,
                    std::span<std::byte>(frame, layout_.page_size));
    ctx_.reset_cpu_mark();  // the wait is not work
    const nodes::NetworkModel& net = ctx_.network();
    const std::uint32_t hops = ctx_.topology().hops(ctx_.id(), home);
    arrival = start + net.message_time(sizeof(PageRequestMsg), hops) +
              net.message_time(std::uint32_t(sizeof(PageReplyMsg) + layout_.page_size), hops);
  } else {
    ctx_.send(home, nodes::MessageType::kPageRequest, PageRequestMsg{page});
    ctx_.note_wait(nodes::WaitReason::kPage, page, home);
    arrival = await_page(page, home, frame, released, m);
  }
  ctx_.note_wait(nodes::WaitReason::kNone);
  ctx_.advance_to(arrival, nodes::WaitKind::kCommunication);
  frame_page_[victim - home_frames_] = page;
  const std::uint32_t offset = victim << layout_.page_shift;
  set_frame_offset(page, offset);
  if (lru_ordered())
    stamp(victim - home_frames_);
  else if (cache_used_ == cache_frames_)
    order_lru(victim - home_frames_);  // the last free frame: from now on, victims are needed
  // Compute again only with a run permit, answering requests meanwhile.
  while (released && !ctx_.try_resume()) {
    ctx_.wait_for_mail(0);
    while (ctx_.poll(m)) serve_or_defer(m);
  }
  ctx_.resume_deferred();
  return offset;
}

}  // namespace raynode::svm
