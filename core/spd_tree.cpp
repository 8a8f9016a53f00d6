// SPD "tree": a binary tree grown by Aono & Kunii's method (IEEE CG&A, May
// 1984): each branch is a cone capped by a sphere, and carries two smaller
// branches; a green square field below, seven lights. Size s gives
// 2^(s+1) - 1 cones and as many spheres (s = 11: 4095 each), one polygon.
// Reproduces Eric Haines' SPD 3.14 tree.c NFF output (default size 11).
//
// All geometry is computed in double, as SPD does, then stored as float.
#include <array>

#include "core/spd_generators.h"

namespace raynode::core::spd {
namespace {

constexpr int kMinSize = 1;
constexpr int kMaxSize = 20;  // 2M cones and 2M spheres

// The shape of the tree (Aono & Kunii's parameters, as SPD sets them).
constexpr double kBranchAngle[2] = {40.0, 25.0};        // degrees, about X
constexpr double kDivergence[2] = {90.0, 140.0 + 90.0};  // degrees, about Z
constexpr double kContraction[2] = {0.65, 0.70};         // length ratio
constexpr double kDiameterRatio = 0.67;                  // child / parent width
constexpr double kWidthHeightRatio = 0.15;

// The transform of each child branch relative to its parent: rotate about
// X by the branching angle, about Z by the divergence, then scale by the
// contraction and move up to the parent's tip.
std::array<Mat4, 2> make_branch_transforms() {
  std::array<Mat4, 2> out;
  for (int i = 0; i < 2; ++i) {
    const Mat4 turn = rotation_matrix(0, kBranchAngle[i] * kSpdPi / 180.0) *
                      rotation_matrix(2, kDivergence[i] * kSpdPi / 180.0);
    Mat4 scale_up = scale_matrix(kContraction[i]);
    scale_up.m[3][2] = 1.0;
    out[i] = turn * scale_up;
  }
  return out;
}

// Writes the branch `m` maps the unit Z segment onto (a cone from radius
// scale * 0.15 to 0.67 of that, then a sphere of the tip radius at the tip),
// then, depth > 0, its two children, depth first.
void grow(Scene& scene, const std::array<Mat4, 2>& branch, const Mat4& m, double scale,
          int depth) {
  const D3 base = transform_point({0.0, 0.0, 0.0}, m);
  const D3 apex = transform_point({0.0, 0.0, 1.0}, m);
  const double base_radius = scale * kWidthHeightRatio;
  const double apex_radius = base_radius * kDiameterRatio;
  scene.add_cone(Cone{as_vec3(base), static_cast<float>(base_radius), as_vec3(apex),
                      static_cast<float>(apex_radius)});
  scene.add_sphere(Sphere{as_vec3(apex), static_cast<float>(apex_radius)});
  if (depth <= 0) return;
  for (const Mat4& b : branch) grow(scene, branch, b * m, scale * kDiameterRatio, depth - 1);
}

}  // namespace

Scene make_tree(int size) {
  check_spd_size("tree", size, kMinSize, kMaxSize);
  Scene scene;
  scene.background = {0.078f, 0.361f, 0.753f};
  set_spd_view(scene, {4.5, 0.4, 2.0}, {0.0, 0.0, 1.5}, {0.0, 0.0, 1.0}, 45.0, 1.0, 512, 512);
  for (const D3& l : {D3{-5.0, 5.0, 50.0}, D3{30.0, -30.0, 30.0}, D3{-40.0, -30.0, 20.0},
                      D3{10.0, 30.0, 40.0}, D3{-30.0, 40.0, 10.0}, D3{50.0, 25.0, 20.0},
                      D3{-10.0, -60.0, 30.0}}) {
    scene.lights.push_back(Light{as_vec3(l)});
  }

  // Green diffuse field.
  scene.materials.push_back(spd_material({0.2, 0.7, 0.2}, 1.0, 0.0, 0.0, 0.0, 0.0));
  const Vec3 field[4] = {{50.0f, 50.0f, 0.0f}, {-50.0f, 50.0f, 0.0f}, {-50.0f, -50.0f, 0.0f},
                         {50.0f, -50.0f, 0.0f}};
  scene.add_polygon(field, 4);

  // Brown diffuse tree.
  scene.materials.push_back(spd_material({0.55, 0.4, 0.2}, 1.0, 0.0, 0.0, 0.0, 0.0));
  const std::size_t branches = (std::size_t{1} << (size + 1)) - 1;
  scene.shapes.reserve(2 * branches + 1);
  scene.cones.reserve(branches);
  scene.spheres.reserve(branches);
  grow(scene, make_branch_transforms(), Mat4{}, 1.0, size);
  return scene;
}

}  // namespace raynode::core::spd
