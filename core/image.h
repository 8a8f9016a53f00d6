// A plain float image: what the renderer produces and imageio writes.
//
// Place in the data flow: render (render.h) -> Image (linear float, no
// colour management, no file format) -> imageio::write_image_as. Core knows no
// image library; the conversion to 8 bits or to EXR halves/floats happens in
// imageio/.
#pragma once

#include <cstddef>
#include <vector>

namespace raynode::core {

/// Row-major width x height image of `channels` floats per pixel (3 = linear
/// RGB, 1 = a single AOV such as depth). Row 0 is the top of the image.
struct Image {
  int width = 0;
  int height = 0;
  int channels = 3;
  std::vector<float> pixels;  ///< width * height * channels floats

  Image() = default;
  Image(int w, int h, int c) : width(w), height(h), channels(c), pixels(std::size_t(w) * h * c, 0.0f) {}

  bool empty() const { return pixels.empty(); }
  /// Pointer to the first channel of pixel (x, y); 0 <= x < width, 0 <= y < height.
  float* at(int x, int y) { return pixels.data() + (std::size_t(y) * width + x) * channels; }
  const float* at(int x, int y) const { return pixels.data() + (std::size_t(y) * width + x) * channels; }
};

}  // namespace raynode::core
