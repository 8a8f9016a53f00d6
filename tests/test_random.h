// Deterministic random helpers shared by the core test suites.
#pragma once

#include <random>

#include "core/math.h"

namespace raynode::testing {

using Rng = std::mt19937_64;

inline float uniform(Rng& rng, float lo, float hi) { return std::uniform_real_distribution<float>(lo, hi)(rng); }

/// A uniformly distributed unit vector.
inline core::Vec3 random_unit(Rng& rng) {
  std::normal_distribution<float> n(0.0f, 1.0f);
  for (;;) {
    const core::Vec3 v{n(rng), n(rng), n(rng)};
    if (core::length(v) > 1e-3f) return core::normalize(v);
  }
}

/// A point uniform in the cube [-h, h]^3.
inline core::Vec3 random_in_cube(Rng& rng, float h) {
  return {uniform(rng, -h, h), uniform(rng, -h, h), uniform(rng, -h, h)};
}

}  // namespace raynode::testing
