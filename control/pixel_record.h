// How a node packs one pixel's results into the floats of a kPixels message
// and how the host unpacks them into its images: RGB, then the requested
// AOVs (depth, normal, primitive), then channels a mode adds (svm's pages
// per pixel). One layout for every node mode, so that what replicated, svm
// and later modes send reads the same way.
//
// Place in the data flow: node: core::render_pixel -> PixelLayout::pack ->
// PixelBatch (work.h); host: gather_pixels -> PixelLayout::unpack ->
// core::RenderResult.
#pragma once

#include <cstdint>
#include <cstring>

#include "core/render.h"

namespace raynode::control {

struct PixelLayout {
  std::uint32_t channels = 3;  ///< floats per pixel
  int depth = -1, normal = -1, primitive = -1;  ///< channel of each AOV, -1 if not sent

  /// RGB plus the AOVs `p` asks for.
  explicit PixelLayout(const core::RenderParams& p) {
    if (p.depth_aov) depth = int(channels++);
    if (p.normal_aov) normal = int(channels), channels += 3;
    if (p.primitive_aov) primitive = int(channels++);
  }
  /// Appends one mode-specific channel; returns its index.
  int add_channel() { return int(channels++); }

  /// Writes px's RGB and AOV channels to out[0 .. channels) (added channels untouched).
  void pack(const core::PixelResult& px, float* out) const {
    out[0] = px.color.x;
    out[1] = px.color.y;
    out[2] = px.color.z;
    if (depth >= 0) out[depth] = px.first.t;
    if (normal >= 0) {
      out[normal] = px.first.normal.x;
      out[normal + 1] = px.first.normal.y;
      out[normal + 2] = px.first.normal.z;
    }
    if (primitive >= 0) out[primitive] = float(px.first.shape);
  }
  /// Stores a packed pixel's RGB and AOVs at (x, y) of `result`'s images
  /// (sized by the caller).
  void unpack(const float* in, int x, int y, core::RenderResult& result) const {
    std::memcpy(result.color.at(x, y), in, 3 * sizeof(float));
    if (depth >= 0) *result.depth.at(x, y) = in[depth];
    if (normal >= 0) std::memcpy(result.normal.at(x, y), in + normal, 3 * sizeof(float));
    if (primitive >= 0) *result.primitive.at(x, y) = in[primitive];
  }
};

}  // namespace raynode::control
