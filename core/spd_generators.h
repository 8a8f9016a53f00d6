// Internal: one function per built-in SPD generator, dispatched by
// make_spd_scene (spd.cpp). Each returns the scene the SPD program writes
// with `-s size` (no -t; tessellation is applied afterwards by
// tessellate_scene). Throw std::invalid_argument for a size out of range.
#pragma once

#include <cmath>

#include "core/scene.h"

namespace raynode::core::spd {

/// A point or direction in double precision, as the SPD programs compute.
struct D3 {
  double x = 0, y = 0, z = 0;
};

/// Right-handed rotation of p by `angle` radians about the unit axis a
/// (SPD's lib_create_axis_rotate_matrix applied to a row vector).
inline D3 rotate(const D3& p, const D3& a, double angle) {
  const double c = std::cos(angle), s = std::sin(angle), t = 1.0 - c;
  return {p.x * (a.x * a.x + (1.0 - a.x * a.x) * c) + p.y * (a.x * a.y * t - a.z * s) +
              p.z * (a.x * a.z * t + a.y * s),
          p.x * (a.x * a.y * t + a.z * s) + p.y * (a.y * a.y + (1.0 - a.y * a.y) * c) +
              p.z * (a.y * a.z * t - a.x * s),
          p.x * (a.x * a.z * t - a.y * s) + p.y * (a.y * a.z * t + a.x * s) +
              p.z * (a.z * a.z + (1.0 - a.z * a.z) * c)};
}

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
