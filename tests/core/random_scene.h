// Random scenes and points for the grid tests and the walk's ISA dump
// (walk_isa_dump.cpp): seeded, so every run and every build of a test sees
// the same scene. Free of doctest, so that programs that are not test
// suites can include it.
#pragma once

#include <cstdint>
#include <random>

#include "core/math.h"
#include "core/scene.h"

namespace raynode::testing::grid {

using Rng = std::mt19937_64;

inline float uniform(Rng& rng, float lo, float hi) { return std::uniform_real_distribution<float>(lo, hi)(rng); }

inline core::Vec3 random_in(Rng& rng, const core::Bounds3& b) {
  return {uniform(rng, b.lower.x, b.upper.x), uniform(rng, b.lower.y, b.upper.y),
          uniform(rng, b.lower.z, b.upper.z)};
}

inline core::Vec3 random_unit(Rng& rng) {
  std::normal_distribution<float> n(0.0f, 1.0f);
  for (;;) {
    const core::Vec3 v{n(rng), n(rng), n(rng)};
    if (length(v) > 1e-3f) return normalize(v);
  }
}

/// Random triangles, spheres and open cones of about `size` (world units)
/// in [-1,1]^3, from `seed`.
inline core::Scene random_scene(std::uint64_t seed, int triangles, int spheres, int cones, float size) {
  Rng rng(seed);
  core::Scene s;
  const core::Bounds3 box{{-1, -1, -1}, {1, 1, 1}};
  for (int i = 0; i < triangles; ++i) {
    const core::Vec3 c = random_in(rng, box);
    const core::Vec3 v[3] = {c + random_unit(rng) * size, c + random_unit(rng) * size, c + random_unit(rng) * size};
    s.add_polygon(v, 3);
  }
  for (int i = 0; i < spheres; ++i) s.add_sphere({random_in(rng, box), size * uniform(rng, 0.2f, 1.0f)});
  for (int i = 0; i < cones; ++i) {
    const core::Vec3 base = random_in(rng, box);
    s.add_cone({base, size * uniform(rng, 0.1f, 0.6f), base + random_unit(rng) * (2 * size),
                size * uniform(rng, 0.0f, 0.6f)});
  }
  return s;
}

}  // namespace raynode::testing::grid
