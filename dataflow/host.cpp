#include "dataflow/host.h"

#include <fmt/core.h>

#include <algorithm>
#include <cstring>
#include <deque>
#include <span>
#include <stdexcept>

#include "dataflow/messages.h"

namespace raynode::dataflow {

using nodes::Message;
using nodes::MessageType;
using nodes::NodeContext;
using nodes::NodeId;

namespace {

/// A spilled ray waiting at the host, and when it may leave again.
struct Stored {
  RayMsg ray;
  double depart;
};

class Host {
 public:
  Host(NodeContext& host, std::uint32_t n, const HostFrame& frame)
      : host_(host), n_(n), frame_(frame), hs_(*frame.stats), store_(n), service_(host.network().service_s) {
    start_wave();
  }

  void run() {
    Message msg;
    while (!done_) {
      forward_stored();
      while (!probes_.empty() &&
             host_.try_send(probes_.back(), MessageType::kToken, TokenMsg{wave_, 0, 0, 0}, {}, 0.0))
        probes_.pop_back();
      if (host_.poll(msg)) {
        handle(msg);
        continue;
      }
      // Nothing came: wait for mail; with rays or probes still to send, retry soon.
      host_.wait_for_mail(stored_ > 0 || !probes_.empty() ? 1e-4 : 0.0);
    }
    for (NodeId i = 0; i < n_; ++i) host_.send(i, MessageType::kShutdown, TokenMsg{wave_, 0, 0, 0}, {}, 0.0);
  }

 private:
  void handle(const Message& msg) {
    switch (msg.type()) {
      case MessageType::kRay: store(msg); break;
      case MessageType::kContribution: add_contributions(msg); break;
      case MessageType::kToken: count_answer(msg.as<TokenMsg>()); break;
      default:
        throw std::logic_error(fmt::format("host: unexpected {} message from {}",
                                           nodes::message_type_name(msg.type()), nodes::node_name(msg.source())));
    }
  }

  /// The spill store: a ray whose destination's mailbox was full.
  void store(const Message& msg) {
    const RayMsg r = msg.as<RayMsg>();
    if (r.region >= n_) throw std::logic_error(fmt::format("host: a spilled ray for region {}", r.region));
    store_[r.region].push_back(Stored{r, msg.header.arrival_time + service_});
    ++stored_;
    ++received_;
    ++hs_.spilled;
    hs_.store_peak = std::max(hs_.store_peak, stored_);
  }

  /// Forwards what the host keeps, as far as the mailboxes have room.
  void forward_stored() {
    if (stored_ == 0) return;
    for (NodeId dest = 0; dest < n_; ++dest) {
      std::deque<Stored>& q = store_[dest];
      while (!q.empty()) {
        if (!host_.try_send(dest, MessageType::kRay, q.front().ray, {}, q.front().depart)) {
          ++hs_.forward_retries;
          break;
        }
        q.pop_front();
        --stored_;
        ++sent_;
        ++hs_.forwarded;
      }
    }
  }

  /// The frame: colour terms summed per pixel (in arrival order), first hits into the AOVs.
  void add_contributions(const Message& msg) {
    const ContributionHeader head = msg.as<ContributionHeader>();
    const std::span<const std::byte> tail = msg.tail<ContributionHeader>();
    const std::size_t rec = head.kind == 0 ? sizeof(Contribution) : sizeof(FirstHitRecord);
    if (tail.size() != head.count * rec)
      throw std::logic_error(
          fmt::format("host: a contribution message from node {} of {} B for {} records of kind {}", msg.source(),
                      tail.size(), head.count, head.kind));
    ++received_;
    const std::uint32_t w = std::uint32_t(frame_.width), pixels = w * std::uint32_t(frame_.height);
    for (std::uint32_t i = 0; i < head.count; ++i) {
      if (head.kind == 0) {
        Contribution c;
        std::memcpy(&c, tail.data() + i * rec, rec);
        if (c.pixel >= pixels) throw std::logic_error(fmt::format("host: a contribution to pixel {}", c.pixel));
        double* s = &(*frame_.sums)[std::size_t(c.pixel) * 3];
        s[0] += c.rgb[0], s[1] += c.rgb[1], s[2] += c.rgb[2];
        ++hs_.contributions;
        continue;
      }
      FirstHitRecord f;
      std::memcpy(&f, tail.data() + i * rec, rec);
      if (f.pixel >= pixels) throw std::logic_error(fmt::format("host: a first hit in pixel {}", f.pixel));
      const int x = int(f.pixel % w), y = int(f.pixel / w);
      core::RenderResult& r = *frame_.render;
      if (!r.depth.empty()) *r.depth.at(x, y) = f.t;
      if (!r.normal.empty()) std::memcpy(r.normal.at(x, y), f.normal, 3 * sizeof(float));
      if (!r.primitive.empty()) *r.primitive.at(x, y) = float(f.shape);
      if (!frame_.region->empty()) *frame_.region->at(x, y) = float(f.region);
      ++hs_.first_hits;
    }
  }

  /// Termination (Mattern's four counters): a node's answer to the current
  /// wave. Two consecutive complete waves with equal totals, sent ==
  /// received, and an empty store end the frame.
  void count_answer(const TokenMsg& t) {
    if (t.wave != wave_) throw std::logic_error(fmt::format("host: an answer to wave {} during wave {}", t.wave, wave_));
    wave_sent_ += t.sent;
    wave_received_ += t.received;
    if (++replies_ < n_) return;
    ++hs_.waves;
    const std::uint64_t s_total = wave_sent_ + sent_, r_total = wave_received_ + received_;
    if (stored_ == 0 && s_total == r_total && have_prev_ && prev_sent_ == s_total && prev_received_ == r_total) {
      done_ = true;
      return;
    }
    prev_sent_ = s_total, prev_received_ = r_total, have_prev_ = true;
    ++wave_;
    start_wave();
  }

  void start_wave() {
    replies_ = 0;
    wave_sent_ = wave_received_ = 0;
    probes_.clear();
    for (NodeId i = n_; i-- > 0;) probes_.push_back(i);
  }

  NodeContext& host_;
  std::uint32_t n_;
  HostFrame frame_;
  HostFlowStats& hs_;
  std::vector<std::deque<Stored>> store_;  ///< spilled rays by destination
  double service_;                         ///< the network's service cost of a forwarded ray
  std::uint64_t stored_ = 0, sent_ = 0, received_ = 0;
  std::uint32_t wave_ = 1, replies_ = 0;
  std::uint64_t wave_sent_ = 0, wave_received_ = 0, prev_sent_ = 0, prev_received_ = 0;
  bool have_prev_ = false, done_ = false;
  std::vector<NodeId> probes_;  ///< still to be sent for the current wave
};

}  // namespace

void run_dataflow_host(NodeContext& host, std::uint32_t nodes, const HostFrame& frame) {
  Host(host, nodes, frame).run();
}

}  // namespace raynode::dataflow
