// Image comparison for the robustness tests: the largest per-channel
// difference (dataflow's tolerance is 1e-5; byte equality is
// testing::same_bytes in test_scenes.h).
#pragma once

#include <algorithm>
#include <cmath>

#include "core/image.h"
#include "core/math.h"

namespace raynode::robustness {

/// Largest |a - b| over all channels; 0 for identical images (equal
/// infinities included); +inf when the shapes differ or a NaN appears.
inline float max_diff(const core::Image& a, const core::Image& b) {
  if (a.width != b.width || a.height != b.height || a.channels != b.channels) return core::kInfinity;
  float m = 0;
  for (std::size_t i = 0; i < a.pixels.size(); ++i) {
    const float x = a.pixels[i], y = b.pixels[i];
    if (x == y) continue;
    const float d = std::fabs(x - y);
    if (!(d <= m)) m = std::isnan(d) ? core::kInfinity : d;
  }
  return m;
}

}  // namespace raynode::robustness
