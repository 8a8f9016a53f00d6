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

/// A 4x4 transform in SPD's layout (MATRIX): a row vector p maps to p * m,
/// translation in row 3. Composition a * b applies a first.
struct Mat4 {
  double m[4][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};
};

/// SPD's lib_matrix_multiply: a * b.
inline Mat4 operator*(const Mat4& a, const Mat4& b) {
  Mat4 r;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      r.m[i][j] = a.m[i][0] * b.m[0][j] + a.m[i][1] * b.m[1][j] + a.m[i][2] * b.m[2][j] +
                  a.m[i][3] * b.m[3][j];
    }
  }
  return r;
}

/// SPD's lib_create_rotate_matrix: right-handed rotation by `angle` radians
/// about axis 0 (X), 1 (Y) or 2 (Z).
inline Mat4 rotation_matrix(int axis, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  Mat4 r;
  const int a = (axis + 1) % 3, b = (axis + 2) % 3;  // X: y,z  Y: z,x  Z: x,y
  r.m[a][a] = c;
  r.m[b][b] = c;
  r.m[a][b] = s;
  r.m[b][a] = -s;
  return r;
}

/// SPD's lib_create_scale_matrix (uniform here).
inline Mat4 scale_matrix(double s) {
  Mat4 r;
  r.m[0][0] = r.m[1][1] = r.m[2][2] = s;
  return r;
}

/// SPD's lib_create_translate_matrix.
inline Mat4 translate_matrix(const D3& t) {
  Mat4 r;
  r.m[3][0] = t.x;
  r.m[3][1] = t.y;
  r.m[3][2] = t.z;
  return r;
}

/// SPD's lib_transform_point: p * m with the translation row.
inline D3 transform_point(const D3& p, const Mat4& m) {
  return {p.x * m.m[0][0] + p.y * m.m[1][0] + p.z * m.m[2][0] + m.m[3][0],
          p.x * m.m[0][1] + p.y * m.m[1][1] + p.z * m.m[2][1] + m.m[3][1],
          p.x * m.m[0][2] + p.y * m.m[1][2] + p.z * m.m[2][2] + m.m[3][2]};
}

/// SPD's lib_transform_vector: p * m without the translation row.
inline D3 transform_vector(const D3& p, const Mat4& m) {
  return {p.x * m.m[0][0] + p.y * m.m[1][0] + p.z * m.m[2][0],
          p.x * m.m[0][1] + p.y * m.m[1][1] + p.z * m.m[2][1],
          p.x * m.m[0][2] + p.y * m.m[1][2] + p.z * m.m[2][2]};
}

/// The float point of a double one (SPD computes in double, raynode stores float).
inline Vec3 as_vec3(const D3& p) {
  return {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)};
}

/// The `f` line SPD's lib_output_color writes for NFF: colour, kd, ks,
/// phong_power(highlight half-angle in degrees), kt, ior (ka and ks_spec are
/// not written).
inline Material spd_material(const D3& color, double kd, double ks, double half_angle_deg,
                             double kt, double ior) {
  Material m;
  m.color = as_vec3(color);
  m.kd = static_cast<float>(kd);
  m.ks = static_cast<float>(ks);
  m.shine = static_cast<float>(phong_power(half_angle_deg));
  m.transmittance = static_cast<float>(kt);
  m.ior = static_cast<float>(ior);
  return m;
}

/// The `v` block SPD's lib_output_viewpoint writes for NFF (angle in degrees,
/// hither in world units, resolution in pixels).
inline void set_spd_view(Scene& scene, const D3& from, const D3& at, const D3& up,
                         double angle_deg, double hither, int width, int height) {
  scene.has_view = true;
  scene.view.from = as_vec3(from);
  scene.view.at = as_vec3(at);
  scene.view.up = as_vec3(up);
  scene.view.angle = static_cast<float>(angle_deg);
  scene.view.hither = static_cast<float>(hither);
  scene.view.width = width;
  scene.view.height = height;
}

/// Throws std::invalid_argument "<name>: size N is out of range lo..hi".
void check_spd_size(const char* name, int size, int min_size, int max_size);

Scene make_teapot(int size);  ///< spd_teapot.cpp; default size 2..
Scene make_mount(int size);   ///< spd_mount.cpp
Scene make_rings(int size);   ///< spd_rings.cpp
Scene make_tetra(int size);   ///< spd_tetra.cpp
Scene make_balls(int size);   ///< spd_balls.cpp
Scene make_gears(int size);     ///< spd_gears.cpp
Scene make_tree(int size);      ///< spd_tree.cpp
Scene make_lattice(int size);   ///< spd_lattice.cpp
Scene make_shells(int size);    ///< spd_shells.cpp
Scene make_jacks(int size);     ///< spd_jacks.cpp
/// jacks with -t R (R >= 1): each jack tessellated in its own frame, then
/// moved, as SPD does under its transform stack (tessellate_scene, which
/// works in world space, would turn the spheres' cube grids differently).
/// Throws std::invalid_argument as tessellate_scene does.
Scene make_jacks_tessellated(int size, int resolution);
Scene make_sombrero(int size);  ///< spd_sombrero.cpp

}  // namespace raynode::core::spd
