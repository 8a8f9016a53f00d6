// Work distribution over the pixels (the paper's control-oriented
// scheduling, reused by replicated and svm modes; docs/architecture.md, "svm"):
// each node owns a submap of the image (near-square parts of equal area, the
// paper's, or with SubmapRule::kBalanced parts of near-equal estimated cost:
// make_balanced_submaps, submap_plan.h), renders it work item by
// work item (default 3x3 pixels) from its near end, and when it runs dry
// sends a work request around the ring embedded in the topology. A busy node
// grants the requester work from its submap: one work item from the far
// end (WorkGrant::kItem, the paper's rule and the emulator's default), the one item
// nearest the requester's last (kNearest), or (kHalf) the far
// half of its remaining item rows as one rectangle, which the requester renders
// as its new submap, item by item, and grants from in turn; an
// idle node forwards the request to its ring successor; a request that
// comes back to its origin unsatisfied means no node has work left to give,
// so the origin's work is over. With WorkRequestRoute::kLastGrantor a
// request starts its walk at the node that granted the requester's last
// item (likely still busy) instead of at the requester's successor; either
// way it passes every other node once, skipping its origin, before it
// returns. With WorkRequestRoute::kOff a node sends no request: its work
// ends with its submap. Finished pixels go to the host, which
// assembles the frame and, once every node has reported done, shuts the
// machine down.
//
// Place in the data flow: mode's node_main -> run_work_farm(ctx, submap,
// render_item, batch) -> render_item(rect) computes pixels into the node's
// PixelBatch; mode's host_main -> gather_pixels(host ctx, image).
//
// Message handling is interrupt-like (node.h): a work request is answered
// at its arrival time plus the network's service cost.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "nodes/machine.h"
#include "nodes/node.h"

namespace raynode::control {

// The emulated machine's names the control-oriented modes speak in (nodes/).
using nodes::Arena;
using nodes::ArenaArray;
using nodes::ArenaExhausted;
using nodes::Awaited;
using nodes::ComputeClock;
using nodes::copy_to_arena;
using nodes::DoesNotFit;
using nodes::format_bytes;
using nodes::kHost;
using nodes::kMaxNodes;
using nodes::Machine;
using nodes::MachineParams;
using nodes::Mailbox;
using nodes::Message;
using nodes::message_type_name;
using nodes::MessageType;
using nodes::node_name;
using nodes::NodeContext;
using nodes::NodeError;
using nodes::NodeId;
using nodes::RunAborted;
using nodes::RunReport;
using nodes::Topology;
using nodes::WaitKind;
using nodes::WaitReason;
using nodes::WorkGrant;
using nodes::WorkRequestRoute;

/// A pixel rectangle [x0, x1) x [y0, y1).
struct Rect {
  std::int32_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  std::int32_t width() const { return x1 - x0; }
  std::int32_t height() const { return y1 - y0; }
  std::int64_t area() const { return std::int64_t(width()) * height(); }
  bool empty() const { return x1 <= x0 || y1 <= y0; }
  bool operator==(const Rect&) const = default;
};

/// How the image is cut into the nodes' static submaps (`--submaps`).
enum class SubmapRule : std::uint8_t {
  kSquare,    ///< near-square, near-equal areas (make_submaps): the paper's
  kBalanced,  ///< near-equal estimated cost (make_balanced_submaps over a host estimate, submap_plan.h)
};
/// "square" or "balanced"; throws std::invalid_argument naming the text otherwise.
SubmapRule parse_submap_rule(const std::string& text);
const char* submap_rule_name(SubmapRule r);

/// Splits width x height into exactly `n` rectangles covering every pixel
/// once, by recursive bisection of the longer side into parts proportional
/// to floor(n/2) : ceil(n/2) nodes, so that every count (not only powers of
/// two) gets near-square submaps of near-equal area. Rectangle i belongs to
/// node i. When n exceeds the pixel count some rectangles are empty.
std::vector<Rect> make_submaps(std::int32_t width, std::int32_t height, std::uint32_t n);

/// make_submaps with each cut placed by cost instead of area
/// (SubmapRule::kBalanced): each bisection cuts the longer side at the
/// pixel column (row) where the first part's share of the rectangle's
/// summed `pixel_cost` (width x height, row-major, >= 0) comes nearest
/// floor(n/2)/n, one pixel from either edge while the side has room;
/// a rectangle of zero cost is cut by area, as make_submaps does. Every
/// pixel lies in exactly one rectangle; rectangle i belongs to node i.
/// When `part_cost` is given, it receives each rectangle's summed cost.
/// O(width x height + n log(width + height)). Throws
/// std::invalid_argument for n = 0, a cost array of the wrong size or a
/// negative or non-finite cost.
std::vector<Rect> make_balanced_submaps(std::int32_t width, std::int32_t height, std::uint32_t n,
                                        std::span<const double> pixel_cost,
                                        std::vector<double>* part_cost = nullptr);

/// The not-yet-started work items of a rectangle, in row-major order of
/// item_w x item_h blocks (the last row/column may be smaller). Taken from
/// the front by the owner, from the back by work requests.
class WorkPool {
 public:
  WorkPool() = default;
  WorkPool(const Rect& area, std::int32_t item_w, std::int32_t item_h);
  bool take_front(Rect& item);
  bool take_back(Rect& item);
  /// Takes the back half of what remains as one rectangle (WorkGrant::kHalf):
  /// half of the whole item rows below the front's row (rounded down), or,
  /// when fewer than two remain or the last row is partly taken, half of
  /// the last row's items (at least one). False when nothing remains.
  bool take_back_half(Rect& rect);
  /// Words of the bitmap that take_nearest needs for a pool over `area`.
  static std::size_t taken_words(const Rect& area, std::int32_t item_w, std::int32_t item_h);
  /// Lets take_nearest take items from anywhere in the pool: `taken`
  /// (taken_words() zeroed words, which must outlive the pool) marks them.
  /// Throws std::invalid_argument when it is too short.
  void allow_any_item(std::span<std::uint64_t> taken);
  /// Takes the item whose centre lies nearest pixel (x, y) (WorkGrant::
  /// kNearest; ties to the later item); take_back when x < 0 or no bitmap
  /// was given. The front and back skip the items it took. O(rows + the
  /// columns searched in them). False when nothing remains.
  bool take_nearest(std::int32_t x, std::int32_t y, Rect& item);
  std::uint32_t remaining() const { return back_ - front_ - taken_inside_; }

 private:
  Rect item(std::uint32_t index) const;
  bool taken(std::uint32_t i) const { return !taken_.empty() && (taken_[i >> 6] >> (i & 63) & 1); }
  Rect area_;
  std::int32_t item_w_ = 1, item_h_ = 1;
  std::uint32_t cols_ = 0;
  std::uint32_t front_ = 0, back_ = 0;
  std::uint32_t taken_inside_ = 0;    ///< items in [front_, back_) that take_nearest took
  std::span<std::uint64_t> taken_;    ///< bit i: item i taken by take_nearest
};

/// Messages of the protocol (trivially copyable; wire size = sizeof).
struct WorkRequestMsg {
  NodeId origin;
  std::uint16_t hops;       ///< hops travelled so far
  std::uint16_t start = 0;  ///< the node where its walk round the ring began
  /// The centre of the requester's last item (pixels; -1: none yet), for
  /// WorkGrant::kNearest.
  std::int32_t near_x = -1, near_y = -1;
};
static_assert(kMaxNodes <= 0xffff, "WorkRequestMsg holds node ids and hops in 16 bits");
struct WorkGrantMsg {
  Rect item;
};
/// Header of a kPixels message: `blocks` pixel blocks follow, each a
/// PixelsMsg and its width*height*channels floats, row-major.
struct PixelBatchMsg {
  std::uint32_t blocks;
};
/// Header of one pixel block in a kPixels message.
struct PixelsMsg {
  Rect rect;
  std::uint32_t channels;
};

/// Counters of the work distribution on one node.
struct WorkStats {
  std::uint64_t items_own = 0;         ///< items rendered from the own submap
  std::uint64_t items_received = 0;    ///< items received by grants (or taken from a granted rectangle) and rendered
  std::uint64_t pixels = 0;            ///< pixels rendered
  std::uint64_t requests_sent = 0;     ///< own requests started
  std::uint64_t requests_forwarded = 0;
  std::uint64_t requests_returned = 0; ///< own request came back: end of work (0 or 1)
  std::uint64_t grants_given = 0;
  std::uint64_t pixels_granted = 0;    ///< pixels of the grants given
  std::uint64_t request_hops = 0;      ///< ring hops of own requests until granted or returned
  double done_time_s = 0;              ///< virtual time the node's work ended
  WorkStats& operator+=(const WorkStats& o);
};

/// Arena bytes that run_work_farm allocates on a node whose submap is the
/// largest of `submaps` under `grant` (WorkGrant::kNearest's taken bits; 0
/// otherwise), for a mode's sum of a node's fixed memory.
std::size_t work_farm_bytes(WorkGrant grant, std::span<const Rect> submaps, std::int32_t item_w, std::int32_t item_h);

/// Handler for messages the farm does not know (svm's page requests...):
/// returns false if it does not know them either (then the farm throws).
using OtherMessageHandler = std::function<bool(NodeContext&, const Message&)>;

/// A node's finished pixel blocks on their way to the host, several in one
/// kPixels message: fewer messages, so fewer looks by the host (and with
/// them fewer of its wake-ups on a core where a node computes; the host
/// needs the pixels only by the end of the run). Blocks are sent in the
/// order they were added; run_work_farm sends the batch before the node
/// asks for work and before it reports done.
///
/// Thread safety: owner node thread only.
class PixelBatch {
 public:
  PixelBatch() = default;
  /// A batch whose buffer, one message's payload (`max_payload` bytes,
  /// rounded down to whole floats), lives in `arena`. Throws ArenaExhausted.
  PixelBatch(Arena& arena, std::uint32_t max_payload)
      : buffer_(arena, max_payload / sizeof(float), "its pixel buffer") {}
  /// Arena bytes of a batch's buffer for `max_payload` (for a mode's sum of
  /// a node's fixed memory).
  static std::size_t bytes(std::uint32_t max_payload) { return max_payload / sizeof(float) * sizeof(float); }
  /// Where to write the rect.area() * channels floats (row-major) of block
  /// `rect`, valid until the next call; sends the batch first when the
  /// block does not fit beside it. Throws std::length_error when one block
  /// needs more than the buffer, and what sending throws.
  float* add(NodeContext& ctx, const Rect& rect, std::uint32_t channels);
  /// Sends the blocks added since the last send, if any, in one message.
  void flush(NodeContext& ctx);
  /// Blocks waiting to be sent.
  std::uint32_t blocks() const { return blocks_; }

 private:
  std::span<std::byte> buffer() const { return std::as_writable_bytes(buffer_.span()); }

  ArenaArray<float> buffer_;
  std::size_t used_ = sizeof(PixelBatchMsg);
  std::uint32_t blocks_ = 0;
};

/// A node's side of the distribution: renders `submap` item by item with
/// render_item(ctx, rect), serving requests between items, then requests
/// work until its request returns, reports done to the host and serves
/// until the host's shutdown. `batch`, when given, is the pixel batch that
/// render_item fills: it is sent before each work request and before the
/// node reports done. Returns the node's counters. Throws what render_item
/// throws, RunAborted, std::logic_error on a protocol error.
WorkStats run_work_farm(NodeContext& ctx, const Rect& submap, std::int32_t item_w, std::int32_t item_h,
                        const std::function<void(NodeContext&, const Rect&)>& render_item,
                        const OtherMessageHandler& other = {}, PixelBatch* batch = nullptr);


/// The host's side: receives pixel blocks and calls store(source, rect,
/// channels, pixels) for each, until every node reported done; then sends
/// shutdown to every node. Returns the number of pixels received. The host
/// only gathers meanwhile (NodeContext::set_host_gathering: its mail queues
/// up between looks), so `other` must answer nothing a node waits for.
std::uint64_t gather_pixels(
    NodeContext& host,
    const std::function<void(NodeId, const Rect&, std::uint32_t, std::span<const float>)>& store,
    const OtherMessageHandler& other = {});

/// Payload bytes a kPixels message of one item_w x item_h block needs.
std::uint32_t pixels_payload_bytes(std::int32_t item_w, std::int32_t item_h, std::uint32_t channels);

}  // namespace raynode::control
