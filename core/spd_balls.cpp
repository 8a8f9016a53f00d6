// SPD "balls" (the sphereflake): a sphere that blooms nine spheres of a third
// its radius, recursively, over a square floor; three lights. Sum over
// n = 0..size of 9^n spheres (size 4: 7381). Reproduces Eric Haines' SPD 3.14
// balls.c NFF output (default size 4).
//
// All geometry is computed in double, as SPD does, with SPD's row-vector
// matrix convention (p' = p * M), then stored as float.
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/spd_generators.h"

namespace raynode::core::spd {
namespace {

constexpr int kMinSize = 1;
constexpr int kMaxSize = 7;  // 9^7: 5.4M spheres
constexpr double kPi = 3.141592653589793;  // SPD's PI

// 3x3 rotation in SPD's layout: a row vector p maps to p * m.
using Mat3 = std::array<std::array<double, 3>, 3>;

D3 mul(const D3& p, const Mat3& m) {
  return {p.x * m[0][0] + p.y * m[1][0] + p.z * m[2][0],
          p.x * m[0][1] + p.y * m[1][1] + p.z * m[2][1],
          p.x * m[0][2] + p.y * m[1][2] + p.z * m[2][2]};
}

D3 normalized(const D3& v) {
  const double len = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
  return len > 0.0 ? D3{v.x / len, v.y / len, v.z / len} : v;
}

Mat3 identity() { return {{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}}; }

// Right-handed rotation by `angle` radians about the unit `axis`.
Mat3 axis_rotation(const D3& a, double angle) {
  const double c = std::cos(angle), s = std::sin(angle), t = 1.0 - c;
  return {{{a.x * a.x + (1.0 - a.x * a.x) * c, a.x * a.y * t + a.z * s, a.x * a.z * t - a.y * s},
           {a.x * a.y * t - a.z * s, a.y * a.y + (1.0 - a.y * a.y) * c, a.y * a.z * t + a.x * s},
           {a.x * a.z * t + a.y * s, a.y * a.z * t - a.x * s, a.z * a.z + (1.0 - a.z * a.z) * c}}};
}

Mat3 z_rotation(double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  return {{{c, s, 0}, {-s, c, 0}, {0, 0, 1}}};
}

Mat3 y_rotation(double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  return {{{c, 0, -s}, {0, 1, 0}, {s, 0, c}}};
}

// The nine child directions around +Z: three trios, each the set
// {(d,d,0), (d,0,-d), (0,d,-d)} (d = 1/sqrt 2) tilted about (1,-1,0) by
// asin(2/sqrt 6), then turned by 0, 120 and 240 degrees about Z.
std::array<D3, 9> make_child_directions() {
  const double d = 1.0 / std::sqrt(2.0);
  std::array<D3, 3> trio = {D3{d, d, 0.0}, D3{d, 0.0, -d}, D3{0.0, d, -d}};
  const Mat3 tilt = axis_rotation(normalized({1.0, -1.0, 0.0}), std::asin(2.0 / std::sqrt(6.0)));
  for (D3& v : trio) v = mul(v, tilt);
  std::array<D3, 9> out{};
  for (int set = 0; set < 3; ++set) {
    const Mat3 turn = z_rotation(set * 2.0 * kPi / 3.0);
    for (int i = 0; i < 3; ++i) out[set * 3 + i] = mul(trio[i], turn);
  }
  return out;
}

struct Flake {
  const std::array<D3, 9>& children;
  Scene& scene;

  // Writes the sphere (center, radius), then, depth > 0, its nine children
  // (radius * ratio) placed around `dir`, each recursing with depth - 1.
  void grow(int depth, const D3& center, double radius, const D3& dir, double ratio) {
    scene.add_sphere(Sphere{{static_cast<float>(center.x), static_cast<float>(center.y),
                             static_cast<float>(center.z)},
                            static_cast<float>(radius)});
    if (depth <= 0) return;
    // Rotation taking +Z to dir. SPD tests with 0.9999 because a child's
    // direction is recomputed and may be slightly shorter than 1.
    Mat3 m;
    if (dir.z >= 0.9999) {
      m = identity();
    } else if (dir.z <= -0.9999) {
      m = y_rotation(kPi);
    } else {
      const D3 axis = normalized({-dir.y, dir.x, 0.0});  // (0,0,1) x dir
      m = axis_rotation(axis, std::acos(dir.z));
    }
    const double scale = radius * (1.0 + ratio);
    for (const D3& c : children) {
      const D3 r = mul(c, m);
      const D3 child{r.x * scale + center.x, r.y * scale + center.y, r.z * scale + center.z};
      const D3 child_dir{(child.x - center.x) / scale, (child.y - center.y) / scale,
                         (child.z - center.z) / scale};
      grow(depth - 1, child, radius * ratio, child_dir, ratio);
    }
  }
};

}  // namespace

Scene make_balls(int size) {
  if (size < kMinSize || size > kMaxSize) {
    throw std::invalid_argument("balls: size " + std::to_string(size) + " is out of range " +
                                std::to_string(kMinSize) + ".." + std::to_string(kMaxSize));
  }
  Scene scene;
  scene.background = {0.078f, 0.361f, 0.753f};
  scene.has_view = true;
  scene.view.from = {2.1f, 1.3f, 1.7f};
  scene.view.at = {0.0f, 0.0f, 0.0f};
  scene.view.up = {0.0f, 0.0f, 1.0f};
  scene.view.angle = 45.0f;
  scene.view.hither = 0.01f;
  scene.view.width = scene.view.height = 512;
  scene.lights.push_back(Light{{4.0f, 3.0f, 2.0f}});
  scene.lights.push_back(Light{{1.0f, -4.0f, 4.0f}});
  scene.lights.push_back(Light{{-3.0f, 1.0f, 5.0f}});

  // Beige floor: kd 0.8, no reflection, no highlight, ior 1.
  Material floor;
  floor.color = {1.0f, 0.75f, 0.33f};
  floor.kd = 0.8f;
  floor.ks = 0.0f;
  floor.shine = static_cast<float>(phong_power(0.0));
  floor.transmittance = 0.0f;
  floor.ior = 1.0f;
  scene.materials.push_back(floor);
  const double radius = 1.0;  // of the sphere enclosing the whole flake
  const float b = static_cast<float>(12.0 * radius), bz = static_cast<float>(-radius / 2.0);
  const Vec3 square[4] = {{b, b, bz}, {-b, b, bz}, {-b, -b, bz}, {b, -b, bz}};
  scene.add_polygon(square, 4);

  // Mirrored spheres: kd 0.5, ks 0.5, highlight half-angle 37 degrees, ior 1.
  Material mirror;
  mirror.color = {1.0f, 0.9f, 0.7f};
  mirror.kd = 0.5f;
  mirror.ks = 0.5f;
  mirror.shine = static_cast<float>(phong_power(37.0));
  mirror.transmittance = 0.0f;
  mirror.ior = 1.0f;
  scene.materials.push_back(mirror);

  const std::array<D3, 9> children = make_child_directions();
  Flake{children, scene}.grow(size, {0.0, 0.0, 0.0}, radius / 2.0, {0.0, 0.0, 1.0}, 1.0 / 3.0);
  return scene;
}

}  // namespace raynode::core::spd
