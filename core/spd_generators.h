// Internal: one function per built-in SPD generator, dispatched by
// make_spd_scene (spd.cpp). Each returns the scene the SPD program writes
// with `-s size` (no -t; tessellation is applied afterwards by
// tessellate_scene). Throw std::invalid_argument for a size out of range.
#pragma once

#include <cmath>

#include "core/scene.h"

namespace raynode::core::spd {

/// SPD's PI.
inline constexpr double kSpdPi = 3.141592653589793;

/// Phong exponent for a highlight that falls to half strength at
/// `half_angle_deg` degrees: ln(0.5) / ln(cos angle); 100000 (the "no
/// highlight" marker) at 0 and 1 at 90 degrees or more (SPD lib_output_color).
inline double phong_power(double half_angle_deg) {
  const double a = kSpdPi * half_angle_deg / 180.0;
  if (a <= 0.0) return 100000.0;
  if (a >= kSpdPi / 2.0) return 1.0;
  return std::log(0.5) / std::log(std::cos(a));
}

Scene make_teapot(int size);  ///< spd_teapot.cpp; default size 2..
Scene make_mount(int size);   ///< spd_mount.cpp
Scene make_rings(int size);   ///< spd_rings.cpp
Scene make_tetra(int size);   ///< spd_tetra.cpp
Scene make_balls(int size);   ///< spd_balls.cpp

}  // namespace raynode::core::spd
