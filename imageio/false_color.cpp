#include "imageio/false_color.h"

#include <algorithm>
#include <cmath>

namespace raynode::imageio {

namespace {

struct Rgb {
  float r, g, b;
};

Rgb ramp(float t) {
  static constexpr Rgb kStops[] = {{0, 0, 0}, {0.1f, 0.1f, 0.7f}, {0.7f, 0.1f, 0.7f},
                                   {1.0f, 0.5f, 0.0f}, {1.0f, 0.95f, 0.1f}, {1, 1, 1}};
  constexpr int kLast = int(std::size(kStops)) - 1;
  t = std::clamp(t, 0.0f, 1.0f) * float(kLast);
  const int i = std::min(int(t), kLast - 1);
  const float f = t - float(i);
  const Rgb& a = kStops[i];
  const Rgb& b = kStops[i + 1];
  return {a.r + (b.r - a.r) * f, a.g + (b.g - a.g) * f, a.b + (b.b - a.b) * f};
}

Rgb hsv(float h, float s, float v) {
  h = (h - std::floor(h)) * 6.0f;
  const int i = int(h) % 6;
  const float f = h - std::floor(h);
  const float p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
  switch (i) {
    case 0: return {v, t, p};
    case 1: return {q, v, p};
    case 2: return {p, v, t};
    case 3: return {p, q, v};
    case 4: return {t, p, v};
    default: return {v, p, q};
  }
}

}  // namespace

core::Image heat_map(const core::Image& values, float max) {
  core::Image out(values.width, values.height, 3);
  if (max <= 0)
    for (std::size_t i = 0; i < values.pixels.size(); i += std::size_t(values.channels))
      max = std::max(max, values.pixels[i]);
  const float inv = max > 0 ? 1.0f / max : 0.0f;
  for (int y = 0; y < values.height; ++y)
    for (int x = 0; x < values.width; ++x) {
      const Rgb c = ramp(*values.at(x, y) * inv);
      float* o = out.at(x, y);
      o[0] = c.r, o[1] = c.g, o[2] = c.b;
    }
  return out;
}

core::Image label_map(const core::Image& labels) {
  core::Image out(labels.width, labels.height, 3);
  for (int y = 0; y < labels.height; ++y)
    for (int x = 0; x < labels.width; ++x) {
      const float l = *labels.at(x, y);
      float* o = out.at(x, y);
      if (!(l >= 0)) continue;
      const Rgb c = hsv(0.61803398875f * l, 0.55f + 0.35f * float(int(l) % 2), 0.95f - 0.25f * float((int(l) / 2) % 2));
      o[0] = c.r, o[1] = c.g, o[2] = c.b;
    }
  return out;
}

}  // namespace raynode::imageio
