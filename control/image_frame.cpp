#include "control/image_frame.h"

#include <fmt/core.h>

#include <stdexcept>

namespace raynode::control {

namespace {

core::Camera frame_camera(const core::Database& db, const core::RenderParams& rp) {
  const core::View view = core::render_view(db);
  return core::Camera(view, rp.width > 0 ? rp.width : view.width, rp.height > 0 ? rp.height : view.height);
}

}  // namespace

ImageFrame image_frame(const core::Database& db, const core::RenderParams& rp, int item_w, int item_h) {
  if (rp.spp < 1) throw std::invalid_argument("spp must be >= 1");
  if (rp.max_depth < 1) throw std::invalid_argument("max depth must be >= 1");
  if (item_w < 1 || item_h < 1)
    throw std::invalid_argument(fmt::format("work item must be at least 1x1, got {}x{}", item_w, item_h));
  const core::Camera camera = frame_camera(db, rp);
  return ImageFrame{camera.width(), camera.height(), camera};
}

void size_images(core::RenderResult& out, const core::RenderParams& rp, const ImageFrame& frame,
                 std::span<core::Image* const> extra) {
  const int w = frame.width, h = frame.height;
  out.color = core::Image(w, h, 3);
  if (rp.depth_aov) out.depth = core::Image(w, h, 1);
  if (rp.normal_aov) out.normal = core::Image(w, h, 3);
  if (rp.primitive_aov) out.primitive = core::Image(w, h, 1);
  for (core::Image* image : extra) *image = core::Image(w, h, 1);
}

void assemble_pixels(NodeContext& host, const PixelLayout& layout, core::RenderResult& out, core::Image& node_aov,
                     std::atomic<std::uint64_t>* progress, std::span<const ExtraChannel> extra) {
  gather_pixels(host, [&](NodeId src, const Rect& r, std::uint32_t ch, std::span<const float> px) {
    if (ch != layout.channels) throw std::logic_error("host: pixel message with the wrong channel count");
    if (progress)  // the progress line counts the pixels the host has received
      progress->fetch_add(std::uint64_t(r.x1 - r.x0) * std::uint64_t(r.y1 - r.y0), std::memory_order_relaxed);
    const float* p = px.data();
    for (int y = r.y0; y < r.y1; ++y)
      for (int x = r.x0; x < r.x1; ++x, p += ch) {
        layout.unpack(p, x, y, out);
        if (!node_aov.empty()) *node_aov.at(x, y) = float(src);
        for (const ExtraChannel& e : extra) *e.image->at(x, y) = p[e.channel];
      }
  });
}

}  // namespace raynode::control
