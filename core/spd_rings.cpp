// SPD "rings": objects made of six pentagonal rings (cylinders joined by
// spheres) through the edge midpoints of a dodecahedron, stacked as a
// pyramid seen from its point, with a white backdrop square behind; three
// lights. Each object has 30 cylinders and 30 spheres; size s gives
// 1 + 4 + ... + s^2 objects (5 s (s+1) (2s+1) of each). Reproduces Eric
// Haines' SPD 3.14 rings.c NFF output (default size 7).
//
// All geometry is computed in double, as SPD does, then stored as float.
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/spd_generators.h"

namespace raynode::core::spd {
namespace {

constexpr int kMinSize = 1;
constexpr int kMaxSize = 40;  // 5*40*41*81 = 664k spheres and as many cylinders
constexpr double kPi = 3.141592653589793;  // SPD's PI
constexpr double kRadius = 0.07412;        // cylinder and sphere radius
constexpr double kSpreadOut = 1.0;         // > 1 spreads succeeding layers out more

// Right-handed rotations about X and Z applied to a row vector, as SPD's
// lib_create_rotate_matrix + lib_transform_point compute them.
D3 rotate_x(const D3& p, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  return {p.x, p.y * c - p.z * s, p.y * s + p.z * c};
}

D3 rotate_z(const D3& p, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  return {p.x * c - p.y * s, p.x * s + p.y * c, p.z};
}

// The 30 ring points: a pentagon in the XY plane (points from +X, a fifth of
// a turn apart) scaled to fit with the tube inside the unit sphere, and five
// copies tipped about X by the dihedral angle between adjacent dodecahedron
// faces, then turned about Z by (2k + 1)/10 of a turn, k = 0..4.
std::array<D3, 30> make_ring_points(double minor_radius) {
  std::array<D3, 30> v{};
  const double scale = 1.0 / (1.0 + minor_radius);
  for (int i = 0; i < 5; ++i) {
    v[i] = {scale * std::cos(i * 2.0 * kPi / 5.0), scale * std::sin(i * 2.0 * kPi / 5.0), 0.0};
  }
  const double x_rotation = 2.0 * std::acos(std::cos(kPi / 3.0) / std::sin(kPi / 5.0));
  for (int p = 1; p < 6; ++p) {
    const double z_rotation = kPi * (2.0 * (p - 1) + 1.0) / 5.0;
    for (int i = 0; i < 5; ++i) v[5 * p + i] = rotate_z(rotate_x(v[i], x_rotation), z_rotation);
  }
  return v;
}

Vec3 to_vec3(const D3& p) {
  return {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)};
}

}  // namespace

Scene make_rings(int size) {
  if (size < kMinSize || size > kMaxSize) {
    throw std::invalid_argument("rings: size " + std::to_string(size) + " is out of range " +
                                std::to_string(kMinSize) + ".." + std::to_string(kMaxSize));
  }
  const double spread = 1.0 / std::sin(kPi / 8.0);
  double y_diff = 1.0, xz_diff = 1.0;
  if (kSpreadOut <= spread) {
    y_diff = spread / kSpreadOut;
  } else {
    xz_diff = kSpreadOut / spread;
  }

  Scene scene;
  scene.background = {0.078f, 0.361f, 0.753f};  // never seen: the backdrop fills the view
  scene.has_view = true;
  const D3 from{-1.0, -spread, 0.5};
  scene.view.from = to_vec3(from);
  scene.view.at = to_vec3({from.x, from.y + 1.0, from.z});
  scene.view.up = {0.0f, 0.0f, 1.0f};
  scene.view.angle = 45.0f;
  scene.view.hither = 1.0f;
  scene.view.width = scene.view.height = 512;
  scene.lights.push_back(Light{to_vec3({3.0, -spread, 3.0})});
  scene.lights.push_back(Light{to_vec3({-4.0, -spread, 1.0})});
  scene.lights.push_back(Light{to_vec3({2.0, -spread, -4.0})});

  // White diffuse backdrop that just spans the 45 degree view, plus 1%.
  Material wall_material;
  wall_material.color = {1.0f, 1.0f, 1.0f};
  wall_material.kd = 1.0f;
  wall_material.ks = 0.0f;
  wall_material.shine = static_cast<float>(phong_power(0.0));
  wall_material.transmittance = 0.0f;
  wall_material.ior = 0.0f;
  scene.materials.push_back(wall_material);
  const double wy = y_diff * (size + 1);
  const double wxz = 1.01 * (wy - from.y) * std::tan(kPi / 8.0);
  const Vec3 wall[4] = {to_vec3({wxz + from.x, wy, wxz + from.z}),
                        to_vec3({-wxz + from.x, wy, wxz + from.z}),
                        to_vec3({-wxz + from.x, wy, -wxz + from.z}),
                        to_vec3({wxz + from.x, wy, -wxz + from.z})};
  scene.add_polygon(wall, 4);

  // Ring colours: red, green, blue and their complements; kd 0.5, ks 0.2,
  // highlight half-angle 37 degrees.
  static constexpr float kRingColor[6][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1},
                                             {0, 1, 1}, {1, 0, 1}, {1, 1, 0}};
  const float ring_shine = static_cast<float>(phong_power(37.0));
  const std::array<D3, 30> ring = make_ring_points(kRadius);
  const float r = static_cast<float>(kRadius);

  for (int depth = 0; depth < size; ++depth) {
    const double oy = y_diff * (depth + 1);
    for (int iz = 0; iz <= depth; ++iz) {
      const double oz = xz_diff * (2 * iz - depth);
      for (int ix = 0; ix <= depth; ++ix) {
        const double ox = xz_diff * (2 * ix - depth);
        for (int e = 0; e < 30; ++e) {
          int prev = e - 1;
          if (e % 5 == 0) {
            prev = e + 4;  // a new ring starts: close it back to its last point
            Material m;
            m.color = {kRingColor[e / 5][0], kRingColor[e / 5][1], kRingColor[e / 5][2]};
            m.kd = 0.5f;
            m.ks = 0.2f;
            m.shine = ring_shine;
            m.transmittance = 0.0f;
            m.ior = 0.0f;
            scene.materials.push_back(m);
          }
          const Vec3 base = to_vec3({ring[e].x + ox, ring[e].y + oy, ring[e].z + oz});
          const Vec3 apex = to_vec3({ring[prev].x + ox, ring[prev].y + oy, ring[prev].z + oz});
          scene.add_cone(Cone{base, r, apex, r});
          scene.add_sphere(Sphere{base, r});
        }
      }
    }
  }
  return scene;
}

}  // namespace raynode::core::spd
