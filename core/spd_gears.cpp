// SPD "gears": size^3 gears of 36 teeth in a cube, stacked in layers that
// mesh, over a reflective square; five lights. Each gear is a concave
// 144-vertex top face, 144 rectangular sides and a 144-vertex bottom face, so
// size s gives 1 + 146 s^3 polygons (s = 4: 9345) and 1 + s^3 materials.
// Reproduces Eric Haines' SPD 3.14 gears.c NFF output (default size 4).
//
// All geometry is computed in double, as SPD does, then stored as float.
#include <algorithm>
#include <array>
#include <cmath>

#include "core/spd_generators.h"

namespace raynode::core::spd {
namespace {

constexpr int kMinSize = 1;
constexpr int kMaxSize = 20;  // 8000 gears, 1.17M polygons
constexpr int kTeeth = 36;    // a multiple of 4
constexpr int kGearPoints = 4 * kTeeth;
constexpr double kOuterEdgeRatio = 0.995;  // keeps meshing gears a hair apart
constexpr double kInnerEdgeRatio = 0.9;
constexpr double kEdgeDiff = 1.0 - kInnerEdgeRatio;  // computed as SPD does
constexpr double kDepthRatio = 0.1;                  // thickness / width

// SPD's FRACTION: x minus its integer part (x >= 0 here).
double fraction(double x) { return x - static_cast<int>(x); }

// The four outline points of one tooth: two on the outer radius at
// angle -+0.19 tooth, two on the inner radius at +0.3 and +0.7 tooth (a
// negative tooth angle mirrors the tooth, as for the bottom face).
void add_tooth(double gear_angle, double tooth_angle, const D3& center, double outer_radius,
               double inner_radius, double z, D3* out) {
  const auto at = [&](double radius, double angle) {
    return D3{radius * std::cos(angle) + center.x, radius * std::sin(angle) + center.y,
              z + center.z};
  };
  out[0] = at(outer_radius, gear_angle - 0.19 * tooth_angle);
  out[1] = at(outer_radius, gear_angle + 0.19 * tooth_angle);
  out[2] = at(inner_radius, gear_angle + 0.3 * tooth_angle);
  out[3] = at(inner_radius, gear_angle + 0.7 * tooth_angle);
}

// One gear: top face (teeth counter-clockwise from offset_angle), the 144
// sides going down by `thickness`, then the bottom face (teeth clockwise, so
// that it faces down).
void add_gear(Scene& scene, const D3& center, double offset_angle, double outer_radius,
              double inner_radius, double thickness) {
  const double tooth_angle = 2.0 * kSpdPi / kTeeth;
  std::array<D3, kGearPoints> pts;
  std::array<Vec3, kGearPoints> face;
  for (int t = 0; t < kTeeth; ++t) {
    const double angle = offset_angle + 2.0 * kSpdPi * t / kTeeth;
    add_tooth(angle, tooth_angle, center, outer_radius, inner_radius, 0.0, &pts[4 * t]);
  }
  for (int i = 0; i < kGearPoints; ++i) face[i] = as_vec3(pts[i]);
  scene.add_polygon(face.data(), kGearPoints);

  for (int i = 0; i < kGearPoints; ++i) {
    const D3& a = pts[i];
    const D3& b = pts[(i + 1) % kGearPoints];
    const Vec3 side[4] = {as_vec3(a), as_vec3({a.x, a.y, a.z - thickness}),
                          as_vec3({b.x, b.y, b.z - thickness}), as_vec3(b)};
    scene.add_polygon(side, 4);
  }

  for (int t = 0; t < kTeeth; ++t) {
    const double angle = offset_angle - 2.0 * kSpdPi * t / kTeeth;
    add_tooth(angle, -tooth_angle, center, outer_radius, inner_radius, -thickness, &pts[4 * t]);
  }
  for (int i = 0; i < kGearPoints; ++i) face[i] = as_vec3(pts[i]);
  scene.add_polygon(face.data(), kGearPoints);
}

}  // namespace

Scene make_gears(int size) {
  check_spd_size("gears", size, kMinSize, kMaxSize);
  Scene scene;
  scene.background = {0.078f, 0.361f, 0.753f};
  set_spd_view(scene, {-1.1, -2.1, 2.6}, {0.0, 0.0, 0.0}, {0.0, 0.0, 1.0}, 45.0, 1.0, 512, 512);
  for (const D3& l : {D3{2.0, 4.0, 4.0}, D3{-2.0, 4.0, 3.0}, D3{2.0, -2.5, 2.5},
                      D3{-1.0, -4.0, 2.0}, D3{-1.111, -2.121, 2.626}}) {
    scene.lights.push_back(Light{as_vec3(l)});
  }

  // Off-white reflective ground: kd 0.3, ks 0.6, highlight 37 degrees.
  scene.materials.push_back(spd_material({1.0, 0.85, 0.7}, 0.3, 0.6, 37.0, 0.0, 0.0));
  const Vec3 ground[4] = {{2.0f, 2.0f, 0.0f}, {-2.0f, 2.0f, 0.0f}, {-2.0f, -2.0f, 0.0f},
                          {2.0f, -2.0f, 0.0f}};
  scene.add_polygon(ground, 4);

  const double s = size;
  const double outer_radius = 1.0 / (s - (s - 1.0) * kEdgeDiff / 2.0);
  const D3 zero{-1.0 + outer_radius, -1.0 + outer_radius, 1.0};
  const double step_xy = outer_radius * (2.0 - kEdgeDiff);
  const double step_z = -1.0 / s;
  const double thickness = std::min(kDepthRatio, 1.0 / (2.0 * s));
  for (int iz = 0; iz < size; ++iz) {
    for (int iy = 0; iy < size; ++iy) {
      for (int ix = 0; ix < size; ++ix) {
        const D3 center{zero.x + ix * step_xy, zero.y + iy * step_xy, zero.z + iz * step_z};
        // Pseudo-random colour, scaled so that its largest channel is 1.
        D3 color{0.01 + fraction((ix * 3 + iy * 2 + iz + 1) * 5.0 / 7.0),
                 0.01 + fraction((iy * 3 + iz * 2 + ix + 1) * 3.0 / 7.0),
                 0.01 + fraction((iz * 3 + ix * 2 + iy + 1) * 2.0 / 7.0)};
        const double scale = std::max(std::max(color.x, color.y), color.z);
        color = {color.x / scale, color.y / scale, color.z / scale};
        // Every fifth gear (by 4x + 2y + z) is glassy: kd 0.2, T 0.8, ior 1.1.
        if ((ix * 4 + iy * 2 + iz) % 5 == 0) {
          scene.materials.push_back(spd_material(color, 0.2, 0.0, 0.0, 0.8, 1.1));
        } else {
          scene.materials.push_back(spd_material(color, 1.0, 0.0, 0.0, 0.0, 0.0));
        }
        // Neighbours are turned half a tooth apart so that they mesh.
        const double angle = kSpdPi * ((ix + iy + iz) % 2) / kTeeth;
        add_gear(scene, center, angle, kOuterEdgeRatio * outer_radius,
                 (1.0 - kEdgeDiff) * outer_radius, thickness);
      }
    }
  }
  return scene;
}

}  // namespace raynode::core::spd
