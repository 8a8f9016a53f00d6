#include "control/work.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <thread>
#include <utility>
#include <stdexcept>

namespace raynode::control {

namespace {

/// The summed-area table of per-pixel costs: (width+1) x (height+1) sums.
struct CostTable {
  std::int32_t width;
  std::span<const double> sat;
  double sum(const Rect& r) const {
    auto at = [&](std::int32_t x, std::int32_t y) { return sat[std::size_t(y) * std::size_t(width + 1) + std::size_t(x)]; };
    return at(r.x1, r.y1) - at(r.x0, r.y1) - at(r.x1, r.y0) + at(r.x0, r.y0);
  }
};

/// Cuts r's longer side for floor(n/2) : ceil(n/2) nodes, by area or (with
/// `cost`) by cost, and recurses; appends the leaves in order.
void split(const Rect& r, std::uint32_t n, const CostTable* cost, std::vector<Rect>& out) {
  if (n == 1) {
    out.push_back(r);
    return;
  }
  const std::uint32_t a = n / 2;
  const bool vertical = r.width() >= r.height();
  const std::int32_t lo = vertical ? r.x0 : r.y0, hi = vertical ? r.x1 : r.y1;
  auto part = [&](std::int32_t cut, bool first) {
    Rect p = r;
    (vertical ? (first ? p.x1 : p.x0) : (first ? p.y1 : p.y0)) = cut;
    return p;
  };
  std::int32_t cut = lo + std::int32_t(std::int64_t(hi - lo) * a / n);  // by area
  if (const double total = cost ? cost->sum(r) : 0.0; total > 0) {
    // The first cut whose first part holds at least a/n of the cost, or the
    // one before it when that comes nearer; one pixel from either edge
    // while the side has room.
    const double want = total * double(a) / double(n);
    std::int32_t l = lo, h = hi;
    while (l < h) {
      const std::int32_t mid = l + (h - l) / 2;
      if (cost->sum(part(mid, true)) >= want) h = mid; else l = mid + 1;
    }
    if (l > lo && want - cost->sum(part(l - 1, true)) < cost->sum(part(l, true)) - want) --l;
    cut = hi - lo >= 2 ? std::clamp(l, lo + 1, hi - 1) : l;
  }
  split(part(cut, true), a, cost, out);
  split(part(cut, false), n - a, cost, out);
}

}  // namespace

std::vector<Rect> make_submaps(std::int32_t width, std::int32_t height, std::uint32_t n) {
  if (n == 0) throw std::invalid_argument("make_submaps: n must be >= 1");
  std::vector<Rect> out;
  out.reserve(n);
  split(Rect{0, 0, width, height}, n, nullptr, out);
  return out;
}

std::vector<Rect> make_balanced_submaps(std::int32_t width, std::int32_t height, std::uint32_t n,
                                        std::span<const double> pixel_cost, std::vector<double>* part_cost) {
  if (n == 0) throw std::invalid_argument("make_balanced_submaps: n must be >= 1");
  if (pixel_cost.size() != std::size_t(width) * std::size_t(height))
    throw std::invalid_argument(fmt::format("make_balanced_submaps: {} pixel costs for a {}x{} image",
                                            pixel_cost.size(), width, height));
  std::vector<double> sat(std::size_t(width + 1) * std::size_t(height + 1), 0.0);
  for (std::int32_t y = 0; y < height; ++y) {
    double row = 0;
    for (std::int32_t x = 0; x < width; ++x) {
      const double c = pixel_cost[std::size_t(y) * std::size_t(width) + std::size_t(x)];
      if (!(c >= 0) || !std::isfinite(c))
        throw std::invalid_argument(fmt::format("make_balanced_submaps: pixel ({}, {}) costs {}", x, y, c));
      row += c;
      sat[std::size_t(y + 1) * std::size_t(width + 1) + std::size_t(x + 1)] =
          sat[std::size_t(y) * std::size_t(width + 1) + std::size_t(x + 1)] + row;
    }
  }
  std::vector<Rect> out;
  out.reserve(n);
  const CostTable table{width, sat};
  split(Rect{0, 0, width, height}, n, &table, out);
  if (part_cost) {
    part_cost->clear();
    for (const Rect& r : out) part_cost->push_back(table.sum(r));
  }
  return out;
}

SubmapRule parse_submap_rule(const std::string& text) {
  if (text == "square") return SubmapRule::kSquare;
  if (text == "balanced") return SubmapRule::kBalanced;
  throw std::invalid_argument("submaps are square or balanced, got '" + text + "'");
}

const char* submap_rule_name(SubmapRule r) { return r == SubmapRule::kBalanced ? "balanced" : "square"; }

namespace {
/// The item columns and rows of `area` in items of item_w x item_h (at
/// least 1x1; the last column and row may be narrower).
std::pair<std::uint32_t, std::uint32_t> item_grid(const Rect& area, std::int32_t item_w, std::int32_t item_h) {
  if (area.empty()) return {0, 0};
  const std::int32_t w = std::max(1, item_w), h = std::max(1, item_h);
  return {std::uint32_t((area.width() + w - 1) / w), std::uint32_t((area.height() + h - 1) / h)};
}
}  // namespace

WorkPool::WorkPool(const Rect& area, std::int32_t item_w, std::int32_t item_h)
    : area_(area), item_w_(std::max(1, item_w)), item_h_(std::max(1, item_h)) {
  const auto [cols, rows] = item_grid(area, item_w, item_h);
  cols_ = cols;
  back_ = cols * rows;
}

Rect WorkPool::item(std::uint32_t index) const {
  const std::int32_t cx = std::int32_t(index % cols_), cy = std::int32_t(index / cols_);
  Rect r;
  r.x0 = area_.x0 + cx * item_w_;
  r.y0 = area_.y0 + cy * item_h_;
  r.x1 = std::min(r.x0 + item_w_, area_.x1);
  r.y1 = std::min(r.y0 + item_h_, area_.y1);
  return r;
}

bool WorkPool::take_front(Rect& out) {
  while (front_ < back_ && taken(front_)) ++front_, --taken_inside_;
  if (front_ >= back_) return false;
  out = item(front_++);
  return true;
}

bool WorkPool::take_back(Rect& out) {
  while (front_ < back_ && taken(back_ - 1)) --back_, --taken_inside_;
  if (front_ >= back_) return false;
  out = item(--back_);
  return true;
}

std::size_t WorkPool::taken_words(const Rect& area, std::int32_t item_w, std::int32_t item_h) {
  const auto [cols, rows] = item_grid(area, item_w, item_h);
  return (std::size_t(cols) * rows + 63) / 64;
}

void WorkPool::allow_any_item(std::span<std::uint64_t> taken) {
  const std::size_t need = taken_words(area_, item_w_, item_h_);
  if (taken.size() < need)
    throw std::invalid_argument(
        fmt::format("WorkPool::allow_any_item: {} items need {} bitmap words, got {}", back_, need, taken.size()));
  taken_ = taken.first(need);
}

bool WorkPool::take_nearest(std::int32_t x, std::int32_t y, Rect& out) {
  if (x < 0 || y < 0 || taken_.empty()) return take_back(out);
  if (remaining() == 0) return false;
  // In each row (from the last), the first untaken item from column `col`
  // rightwards and the first leftwards of it: the centres' distance grows
  // with the column away from x's column on either side. Distances between
  // doubled centres, exact in integers.
  const std::int64_t tx = 2 * std::int64_t(x), ty = 2 * std::int64_t(y);
  const std::int32_t col = std::clamp((x - area_.x0) / item_w_, 0, std::int32_t(cols_) - 1);
  std::int64_t best_d = INT64_MAX;
  std::uint32_t best = back_;
  for (std::uint32_t row = (back_ - 1) / cols_ + 1; row-- > front_ / cols_;) {
    const Rect first = item(row * cols_);
    const std::int64_t dy = ty - (first.y0 + first.y1);
    if (dy * dy > best_d) continue;
    const std::uint32_t lo = std::max(front_, row * cols_), hi = std::min(back_, (row + 1) * cols_);
    const std::uint32_t c = std::clamp(row * cols_ + std::uint32_t(col), lo, hi - 1);
    auto consider = [&](std::uint32_t i) {
      const Rect r = item(i);
      const std::int64_t dx = tx - (r.x0 + r.x1), d = dx * dx + dy * dy;
      if (d < best_d || (d == best_d && i > best)) best_d = d, best = i;
    };
    std::uint32_t right = c;
    while (right < hi && taken(right)) ++right;
    if (right < hi) consider(right);
    std::uint32_t left = c;
    while (left > lo && taken(left - 1)) --left;
    if (left > lo) consider(left - 1);
  }
  if (best == back_) return false;
  if (best + 1 == back_) return take_back(out);  // the ends move, the bitmap stays for the middle
  if (best == front_) return take_front(out);
  taken_[best >> 6] |= std::uint64_t(1) << (best & 63);
  ++taken_inside_;
  out = item(best);
  return true;
}

bool WorkPool::take_back_half(Rect& out) {
  if (front_ >= back_) return false;
  const std::uint32_t first_whole_row = (front_ + cols_ - 1) / cols_;  // rows from here on are untouched by the front
  const std::uint32_t whole_rows = back_ % cols_ == 0 ? back_ / cols_ - first_whole_row : 0;
  const std::uint32_t old_back = back_;
  if (whole_rows >= 2) {
    back_ -= whole_rows / 2 * cols_;
  } else {
    // The last row's remaining items, contiguous: the back half of them.
    const std::uint32_t row_start = std::max(front_, (back_ - 1) / cols_ * cols_);
    back_ -= std::max(1u, (back_ - row_start) / 2);
  }
  // Whole rows, or items of one row: their first and last items span them.
  const Rect first = item(back_), last = item(old_back - 1);
  out = Rect{first.x0, first.y0, last.x1, last.y1};
  return true;
}

std::size_t work_farm_bytes(WorkGrant grant, std::span<const Rect> submaps, std::int32_t item_w, std::int32_t item_h) {
  if (grant != WorkGrant::kNearest) return 0;
  std::size_t words = 0;
  for (const Rect& r : submaps) words = std::max(words, WorkPool::taken_words(r, item_w, item_h));
  return words * sizeof(std::uint64_t);
}

WorkStats& WorkStats::operator+=(const WorkStats& o) {
  items_own += o.items_own;
  items_received += o.items_received;
  pixels += o.pixels;
  requests_sent += o.requests_sent;
  requests_forwarded += o.requests_forwarded;
  requests_returned += o.requests_returned;
  grants_given += o.grants_given;
  pixels_granted += o.pixels_granted;
  request_hops += o.request_hops;
  done_time_s = std::max(done_time_s, o.done_time_s);
  return *this;
}

std::uint32_t pixels_payload_bytes(std::int32_t item_w, std::int32_t item_h, std::uint32_t channels) {
  return std::uint32_t(sizeof(PixelBatchMsg) + sizeof(PixelsMsg) +
                       std::size_t(item_w) * item_h * channels * sizeof(float));
}

namespace {
/// The departure stamp of a kPixels message. The host is outside the
/// emulated machine and no figure uses its clock: under the CPU clock a
/// message leaves stamped with the node's last synchronised clock, which
/// saves a system call per message.
double pixels_departure(NodeContext& ctx) {
  return ctx.compute_clock() == ComputeClock::kCpu ? ctx.last_synced_clock() : -1;
}
}  // namespace

float* PixelBatch::add(NodeContext& ctx, const Rect& rect, std::uint32_t channels) {
  const std::size_t need = sizeof(PixelsMsg) + std::size_t(rect.area()) * channels * sizeof(float);
  if (used_ + need > buffer().size()) {
    flush(ctx);
    if (used_ + need > buffer().size())
      throw std::length_error(fmt::format("{}: a {}x{}x{} pixel block needs {} B, the pixel buffer holds {} B",
                                          node_name(ctx.id()), rect.width(), rect.height(), channels,
                                          sizeof(PixelBatchMsg) + need, buffer().size()));
  }
  const PixelsMsg head{rect, channels};
  std::byte* at = buffer().data() + used_;
  std::memcpy(at, &head, sizeof head);
  used_ += need;
  ++blocks_;
  return reinterpret_cast<float*>(at + sizeof head);
}

void PixelBatch::flush(NodeContext& ctx) {
  if (blocks_ == 0) return;
  const PixelBatchMsg head{blocks_};
  std::memcpy(buffer().data(), &head, sizeof head);
  const std::span<const std::byte> parts[1] = {buffer().first(used_)};
  ctx.send(kHost, MessageType::kPixels, std::span<const std::span<const std::byte>>(parts, 1),
           pixels_departure(ctx));
  used_ = sizeof(PixelBatchMsg);
  blocks_ = 0;
}

namespace {

/// The farm's state machine on one node.
class Farm {
 public:
  Farm(NodeContext& ctx, const OtherMessageHandler& other) : ctx_(ctx), other_(other) {}

  /// Serves a message at interrupt level; returns true if it was our own
  /// request coming back (end of work).
  bool handle(const Message& m, WorkPool& pool, bool& have_grant, Rect& grant) {
    switch (m.type()) {
      case MessageType::kWorkRequest: {
        WorkRequestMsg r = m.as<WorkRequestMsg>();
        if (r.origin == ctx_.id()) {
          stats.request_hops += r.hops;
          ++stats.requests_returned;
          return true;
        }
        Rect item;
        const double at = ctx_.serve_interrupt(m.header.arrival_time, ctx_.network().reply_service_s());
        const WorkGrant rule = ctx_.work_grant();
        if (rule == WorkGrant::kHalf      ? pool.take_back_half(item)
            : rule == WorkGrant::kNearest ? pool.take_nearest(r.near_x, r.near_y, item)
                                          : pool.take_back(item)) {
          ctx_.send(r.origin, MessageType::kWorkGrant, WorkGrantMsg{item}, {}, at);
          ++stats.grants_given;
          stats.pixels_granted += std::uint64_t(item.area());
        } else {
          ++r.hops;
          // On round the ring, past the origin, back to the origin when the
          // next node would be where the walk began.
          const Topology& topo = ctx_.topology();
          NodeId next = topo.ring_next(ctx_.id());
          if (next == r.origin) next = topo.ring_next(r.origin);
          if (next == r.start) next = r.origin;
          ctx_.send(next, MessageType::kWorkRequest, r, {}, at);
          ++stats.requests_forwarded;
        }
        return false;
      }
      case MessageType::kWorkGrant:
        if (have_grant) throw std::logic_error(fmt::format("{}: a second work grant while one is pending",
                                                           node_name(ctx_.id())));
        grant = m.as<WorkGrantMsg>().item;
        have_grant = true;
        last_grantor = m.source();
        return false;
      default:
        if (other_ && other_(ctx_, m)) return false;
        throw std::logic_error(fmt::format("{}: unexpected {} message from {} during the work phase",
                                           node_name(ctx_.id()), message_type_name(m.type()),
                                           node_name(m.source())));
    }
  }

  NodeContext& ctx_;
  const OtherMessageHandler& other_;
  WorkStats stats;
  NodeId last_grantor = kHost;  ///< the node that granted our last item (kHost: none yet)
};

}  // namespace

WorkStats run_work_farm(NodeContext& ctx, const Rect& submap, std::int32_t item_w, std::int32_t item_h,
                        const std::function<void(NodeContext&, const Rect&)>& render_item,
                        const OtherMessageHandler& other, PixelBatch* batch) {
  Farm farm(ctx, other);
  WorkPool pool(submap, item_w, item_h);
  ArenaArray<std::uint64_t> taken;  // WorkGrant::kNearest: the items granted from the pool's middle
  if (ctx.work_grant() == WorkGrant::kNearest) {
    taken = ArenaArray<std::uint64_t>(ctx.arena(), WorkPool::taken_words(submap, item_w, item_h),
                                      "its work items' taken bits");
    pool.allow_any_item(taken.span());
  }
  bool own_pool = true;  // false once the pool is a granted rectangle (WorkGrant::kHalf)
  bool have_grant = false, request_out = false, done = false;
  Rect grant;
  std::int32_t last_x = -1, last_y = -1;  // the centre of our last item (WorkGrant::kNearest's point)
  auto rendering = [&](const Rect& r) { last_x = (r.x0 + r.x1) / 2, last_y = (r.y0 + r.y1) / 2; };
  Message m;
  while (!done) {
    // Interrupts first: requests are answered while we still have items.
    while (!done && ctx.poll(m)) done = farm.handle(m, pool, have_grant, grant);
    if (done) break;
    // Virtual-time scheduling (scheduler.h): compute only with a run
    // permit, and hand it over to nodes lagging behind, serving mail while
    // waiting, so that who steals from whom follows virtual time rather
    // than the host's thread scheduling.
    if ((pool.remaining() > 0 || have_grant) && !(ctx.try_run() && ctx.yield_point())) {
      ctx.wait_for_mail(0);
      continue;
    }
    if (have_grant && ctx.work_grant() == WorkGrant::kHalf) {
      // The granted rectangle is our submap now: rendered item by item
      // from its near end, granted from at its far end. Its first item is
      // taken at once, before any request is served: every grant is
      // worked on by its receiver.
      have_grant = false;
      request_out = false;
      pool = WorkPool(grant, item_w, item_h);
      own_pool = false;
    }
    Rect item;
    if (pool.take_front(item)) {
      rendering(item);
      render_item(ctx, item);
      ++(own_pool ? farm.stats.items_own : farm.stats.items_received);
      farm.stats.pixels += std::uint64_t(item.area());
      continue;
    }
    if (have_grant) {
      have_grant = false;
      request_out = false;
      rendering(grant);
      render_item(ctx, grant);
      ++farm.stats.items_received;
      farm.stats.pixels += std::uint64_t(grant.area());
      continue;
    }
    if (ctx.work_request_route() == WorkRequestRoute::kOff) break;  // static submaps only: our work is over
    if (!request_out) {
      if (batch) batch->flush(ctx);  // the host gets our pixels before we idle
      NodeId first = ctx.topology().ring_next(ctx.id());
      if (ctx.work_request_route() == WorkRequestRoute::kLastGrantor && farm.last_grantor != kHost)
        first = farm.last_grantor;
      ctx.send(first, MessageType::kWorkRequest, WorkRequestMsg{ctx.id(), 1, std::uint16_t(first), last_x, last_y});
      ++farm.stats.requests_sent;
      request_out = true;
    }
    // Wait for the grant (or our request's return). Other mail (requests
    // to forward, the mode's messages) is served at interrupt level at its
    // own arrival time and must not move our clock: only the message we
    // wait for does (a forwarded request stamped later than our grant would
    // otherwise count as idle time we never had).
    bool released = false;
    ctx.note_wait(WaitReason::kWorkGrant);
    while (true) {
      if (!ctx.poll(m)) {
        if (!released) {
          ctx.await_reply(Awaited::kWork);  // blocked: let a node behind us compute, none past our clock
          released = true;
        }
        ctx.wait_for_mail(0);
        continue;
      }
      const bool awaited = m.type() == MessageType::kWorkGrant ||
                           (m.type() == MessageType::kWorkRequest && m.as<WorkRequestMsg>().origin == ctx.id());
      if (awaited) ctx.advance_to(m.header.arrival_time, WaitKind::kIdle);
      done = farm.handle(m, pool, have_grant, grant);
      if (awaited) break;
    }
    ctx.note_wait(WaitReason::kNone);
  }
  if (batch) batch->flush(ctx);
  ctx.release_run();  // our work is over
  ctx.mark_work_done();
  farm.stats.done_time_s = ctx.work_done_time();
  ctx.send(kHost, MessageType::kNodeDone, WorkRequestMsg{ctx.id(), 0});
  // Serve others (forward their requests, mode messages) until shutdown.
  while (true) {
    // Interrupt level (no clock move): our work time is recorded.
    while (!ctx.poll(m)) ctx.wait_for_mail(0);
    if (m.type() == MessageType::kShutdown) break;
    farm.handle(m, pool, have_grant, grant);
    if (have_grant) throw std::logic_error(fmt::format("{}: a work grant after its work ended", node_name(ctx.id())));
  }
  return farm.stats;
}

std::uint64_t gather_pixels(
    NodeContext& host,
    const std::function<void(NodeId, const Rect&, std::uint32_t, std::span<const float>)>& store,
    const OtherMessageHandler& other) {
  host.set_host_gathering(true);  // nothing here answers a node: let the pixels queue up between looks
  const std::uint32_t n = host.node_count();
  std::uint32_t done = 0;
  std::uint64_t pixels = 0;
  std::vector<float> buffer;
  while (done < n) {
    const Message m = host.receive(WaitKind::kIdle);
    switch (m.type()) {
      case MessageType::kPixels: {
        std::span<const std::byte> rest = m.tail<PixelBatchMsg>();
        const std::uint32_t blocks = m.as<PixelBatchMsg>().blocks;
        for (std::uint32_t b = 0; b < blocks; ++b) {
          PixelsMsg head;
          if (rest.size() < sizeof head)
            throw std::logic_error(fmt::format("host: pixel message from {} ends in block {} of {}",
                                               node_name(m.source()), b, blocks));
          std::memcpy(&head, rest.data(), sizeof head);
          const std::size_t count = std::size_t(std::max<std::int64_t>(head.rect.area(), 0)) * head.channels;
          if (rest.size() - sizeof head < count * sizeof(float))
            throw std::logic_error(fmt::format("host: pixel message from {} has {} B for a {}x{}x{} block",
                                               node_name(m.source()), rest.size() - sizeof head,
                                               head.rect.width(), head.rect.height(), head.channels));
          buffer.resize(count);
          std::memcpy(buffer.data(), rest.data() + sizeof head, count * sizeof(float));
          store(m.source(), head.rect, head.channels, buffer);
          pixels += std::uint64_t(head.rect.area());
          rest = rest.subspan(sizeof head + count * sizeof(float));
        }
        if (!rest.empty())
          throw std::logic_error(fmt::format("host: pixel message from {} has {} B after its {} blocks",
                                             node_name(m.source()), rest.size(), blocks));
        break;
      }
      case MessageType::kNodeDone: ++done; break;
      default:
        if (other && other(host, m)) break;
        throw std::logic_error(fmt::format("host: unexpected {} message from {}", message_type_name(m.type()),
                                           node_name(m.source())));
    }
  }
  for (NodeId i = 0; i < n; ++i) host.send(i, MessageType::kShutdown, WorkRequestMsg{kHost, 0});
  return pixels;
}

}  // namespace raynode::control
