// SPD "jacks" (Alexander Enzmann): a recursive jack, sort of like a Menger
// sponge. A jack is three crossed cylinders (NFF cones) with a sphere at
// each of the six ends; a smaller copy sits in each of its eight octants,
// down to the size's depth, the whole turned about X and Y; one light. Size
// s gives J = (8^s - 1) / 7 jacks: 3 J cones and 6 J spheres (s = 3: 219 and
// 438). Reproduces Eric Haines' SPD 3.14 jacks.c NFF output (default size 1).
//
// SPD builds each jack in its own frame and writes it through its transform
// stack (lib_tx_*): NFF output moves the points and multiplies the radii by
// the frame's X scale (the length of the matrix's first row). raynode does
// the same in double, then stores float.
#include <cmath>

#include "core/spd_generators.h"

namespace raynode::core::spd {
namespace {

constexpr int kMinSize = 1;
constexpr int kMaxSize = 7;  // 299593 jacks: 899k cones, 1.8M spheres

// SPD lib_tx_unwind's X scale factor: the length of the first row.
double x_scale(const Mat4& m) {
  return std::sqrt(m.m[0][0] * m.m[0][0] + m.m[0][1] * m.m[0][1] + m.m[0][2] * m.m[0][2]);
}

// One jack in the frame `frame` (shrunk by 0.75 to leave room between copies):
// cylinders of radius 0.1 along X, Y, Z from -1 to 1, then spheres of radius
// 0.2 at +X, +Y, +Z, -X, -Y, -Z.
void add_jack(Scene& scene, const Mat4& frame) {
  const Mat4 m = scale_matrix(0.75) * frame;
  const double scale = std::fabs(x_scale(m));
  const float cylinder_radius = static_cast<float>(0.1 * scale);
  const float sphere_radius = static_cast<float>(0.2 * scale);
  static constexpr D3 kAxis[3] = {{1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, {0.0, 0.0, 1.0}};
  for (const D3& a : kAxis) {
    scene.add_cone(Cone{as_vec3(transform_point({-a.x, -a.y, -a.z}, m)), cylinder_radius,
                        as_vec3(transform_point(a, m)), cylinder_radius});
  }
  for (const D3& a : kAxis) scene.add_sphere(Sphere{as_vec3(transform_point(a, m)), sphere_radius});
  for (const D3& a : kAxis) {
    scene.add_sphere(Sphere{as_vec3(transform_point({-a.x, -a.y, -a.z}, m)), sphere_radius});
  }
}

// A jack, then (depth < max_depth) a half-size copy centred at each octant
// corner (+-0.5, +-0.5, +-0.5), x outermost, each -0.5 first.
void add_recursive_jack(Scene& scene, const Mat4& frame, int depth, int max_depth) {
  add_jack(scene, frame);
  if (depth >= max_depth) return;
  for (double i = -0.5; i <= 0.5; i += 1.0) {
    for (double j = -0.5; j <= 0.5; j += 1.0) {
      for (double k = -0.5; k <= 0.5; k += 1.0) {
        const Mat4 child = scale_matrix(0.5) * (translate_matrix({i, j, k}) * frame);
        add_recursive_jack(scene, child, depth + 1, max_depth);
      }
    }
  }
}

}  // namespace

Scene make_jacks(int size) {
  check_spd_size("jacks", size, kMinSize, kMaxSize);
  Scene scene;
  scene.background = {0.2f, 0.05f, 0.2f};  // dark purple
  set_spd_view(scene, {0.0, 0.0, -8.0}, {0.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, 25.0, 0.001, 256, 256);
  scene.lights.push_back(Light{{-10.0f, 3.0f, -20.0f}});

  // Pink: kd 0.7, ks 0.7, highlight 20 degrees, ior 1.
  scene.materials.push_back(spd_material({0.737, 0.561, 0.561}, 0.7, 0.7, 20.0, 0.0, 1.0));

  // Everything turned -30 degrees about X, then -20 degrees about Y.
  const Mat4 root = rotation_matrix(1, -20.0 * kSpdPi / 180.0) *
                    (rotation_matrix(0, -30.0 * kSpdPi / 180.0) * Mat4{});
  add_recursive_jack(scene, root, 1, size);
  return scene;
}

}  // namespace raynode::core::spd
