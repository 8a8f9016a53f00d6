// The image-space frame of the control-oriented modes, replicated and svm
// (the paper's "Control-oriented parallelization"): the frame's size and
// camera, its output images, a node's loop over the work items of its
// submap, and the host's assembly of the pixel blocks the nodes send. A
// mode keeps only what is its own: where a node's database lives (a copy,
// or pages) and the view the tracer reads it through.
//
// Place in the data flow: mode -> image_frame, size_images (host, before
// the run) -> render_items (node: work farm -> core::render_pixel ->
// PixelLayout::pack -> PixelBatch) -> assemble_pixels (host: gather_pixels
// -> PixelLayout::unpack -> core::RenderResult).
#pragma once

#include <atomic>
#include <cstdint>
#include <span>

#include "core/camera.h"
#include "core/database.h"
#include "core/image.h"
#include "core/render.h"
#include "nodes/node.h"
#include "control/pixel_record.h"
#include "control/work.h"

namespace raynode::control {

/// A frame's size in pixels and its camera.
struct ImageFrame {
  int width, height;
  core::Camera camera;
};

/// The frame of `db`'s view at rp's size (the view's own where rp gives
/// none). Throws std::invalid_argument for spp < 1, max_depth < 1, or a
/// work item (item_w x item_h pixels) smaller than 1x1, and what
/// core::Camera throws.
ImageFrame image_frame(const core::Database& db, const core::RenderParams& rp, int item_w, int item_h);

/// Sizes `out`'s colour image and the AOVs `rp` asks for to the frame, and
/// each one-channel image of `extra` (a mode's own AOVs: the node that
/// rendered a pixel, svm's pages per pixel).
void size_images(core::RenderResult& out, const core::RenderParams& rp, const ImageFrame& frame,
                 std::span<core::Image* const> extra = {});

/// What a node's pixel loop reads besides its view, all in the node's memory.
struct PixelJob {
  const core::ShadingContext& shading;
  const core::Camera& camera;
  int spp;               ///< samples per pixel per axis
  bool first_hit;        ///< the AOVs need each pixel's first hit
  const PixelLayout& layout;
  core::ShadingScratch& scratch;
  PixelBatch& batch;
};

/// A mode's hooks in the pixel loop; this one does nothing.
struct NoPixelHooks {
  void begin_pixel() {}           ///< before a pixel is traced
  void after_pixel(float*) {}     ///< the pixel's packed floats, to add a mode's own channels
  void end_item() {}              ///< after a work item's last pixel
};

/// A node's side of the frame: the work farm (work.h) over `submap`, each
/// item_w x item_h work item traced pixel by pixel with core::render_pixel
/// over `view`, packed into the job's batch. `other` answers the messages
/// the farm does not know (svm's page requests). Returns the node's work
/// counters; throws what the farm and the tracer throw.
template <class View, class Hooks = NoPixelHooks>
WorkStats render_items(NodeContext& ctx, const Rect& submap, int item_w, int item_h, const View& view,
                       const PixelJob& job, Hooks&& hooks = {}, const OtherMessageHandler& other = {}) {
  return run_work_farm(
      ctx, submap, item_w, item_h,
      [&](NodeContext& c, const Rect& r) {
        float* o = job.batch.add(c, r, job.layout.channels);
        for (int y = r.y0; y < r.y1; ++y)
          for (int x = r.x0; x < r.x1; ++x) {
            hooks.begin_pixel();
            job.layout.pack(core::render_pixel(view, job.shading, job.camera, x, y, job.spp, job.first_hit, job.scratch),
                            o);
            hooks.after_pixel(o);
            o += job.layout.channels;
          }
        hooks.end_item();
      },
      other, &job.batch);
}

/// An image a mode fills from one channel of the packed pixels.
struct ExtraChannel {
  int channel;
  core::Image* image;
};

/// The host's side of the frame: gathers the nodes' pixel blocks
/// (gather_pixels) into `out` by `layout`, counts them on `progress` when it
/// is non-null (the progress line), writes the source node of each pixel
/// into `node_aov` when it is non-empty, and each of `extra`'s channels into
/// its image. Throws std::logic_error for a block with another channel
/// count.
void assemble_pixels(NodeContext& host, const PixelLayout& layout, core::RenderResult& out, core::Image& node_aov,
                     std::atomic<std::uint64_t>* progress, std::span<const ExtraChannel> extra = {});

}  // namespace raynode::control
