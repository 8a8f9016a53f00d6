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
//
// Tessellated (-t R), SPD polygonalises each cylinder and sphere in the
// jack's own frame and then moves the triangles: points by the frame,
// normals by its inverse transpose (lib_transform_normal, not renormalised,
// so they come out 1 / scale long). make_jacks_tessellated does the same,
// so the cube grid on each sphere turns with its jack. (SPD's jacks.c fixes
// its resolution at 2 whatever -t says: `jacks -s N -t` is jacks:N -t 2.)
#include <fmt/core.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "core/spd.h"
#include "core/spd_generators.h"

namespace raynode::core::spd {
namespace {

constexpr int kMinSize = 1;
constexpr int kMaxSize = 7;  // 299593 jacks: 899k cones, 1.8M spheres

// SPD lib_tx_unwind's X scale factor: the length of the first row.
double x_scale(const Mat4& m) {
  return std::sqrt(m.m[0][0] * m.m[0][0] + m.m[0][1] * m.m[0][1] + m.m[0][2] * m.m[0][2]);
}

// One jack in its own frame, as jacks.c's make_jack_obj writes it before the
// transform: cylinders of radius 0.1 along X, Y, Z from -1 to 1, then
// spheres of radius 0.2 at +X, +Y, +Z, -X, -Y, -Z.
Scene local_jack() {
  Scene jack;
  jack.materials.push_back(Material{});
  static constexpr D3 kAxis[3] = {{1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, {0.0, 0.0, 1.0}};
  for (const D3& a : kAxis) jack.add_cone(Cone{as_vec3({-a.x, -a.y, -a.z}), 0.1f, as_vec3(a), 0.1f});
  for (const D3& a : kAxis) jack.add_sphere(Sphere{as_vec3(a), 0.2f});
  for (const D3& a : kAxis) jack.add_sphere(Sphere{as_vec3({-a.x, -a.y, -a.z}), 0.2f});
  return jack;
}

// Writes `jack` (local_jack(), or its tessellation) moved into `frame`
// shrunk by 0.75 (room between copies), as SPD's NFF output moves it.
void add_jack(Scene& scene, const Scene& jack, const Mat4& frame) {
  const Mat4 m = scale_matrix(0.75) * frame;
  const double scale = std::fabs(x_scale(m));
  const double scale2 = scale * scale;
  for (const Shape& s : jack.shapes) {
    switch (s.kind) {
      case ShapeKind::kCone: {
        const Cone& c = jack.cones[s.first];
        scene.add_cone(Cone{as_vec3(transform_point({c.base.x, c.base.y, c.base.z}, m)),
                            static_cast<float>(c.base_radius * scale),
                            as_vec3(transform_point({c.apex.x, c.apex.y, c.apex.z}, m)),
                            static_cast<float>(c.apex_radius * scale)});
        break;
      }
      case ShapeKind::kSphere: {
        const Sphere& p = jack.spheres[s.first];
        scene.add_sphere(Sphere{as_vec3(transform_point({p.center.x, p.center.y, p.center.z}, m)),
                                static_cast<float>(p.radius * scale)});
        break;
      }
      case ShapeKind::kPatch: {
        Vec3 v[3], n[3];
        for (std::uint32_t k = 0; k < 3; ++k) {
          const Vec3& p = jack.vertices[s.first + k];
          v[k] = as_vec3(transform_point({p.x, p.y, p.z}, m));
          // n (M^-1)^T for M = scale * rotation: n M / scale^2.
          const Vec3& q = jack.normals[s.first_normal + k];
          const D3 d = transform_vector({q.x, q.y, q.z}, m);
          n[k] = as_vec3({d.x / scale2, d.y / scale2, d.z / scale2});
        }
        scene.add_patch(v, n, 3);
        break;
      }
      case ShapeKind::kPolygon:
        break;  // a jack has none
    }
  }
}

// A jack, then (depth < max_depth) a half-size copy centred at each octant
// corner (+-0.5, +-0.5, +-0.5), x outermost, each -0.5 first.
void add_recursive_jack(Scene& scene, const Scene& jack, const Mat4& frame, int depth,
                        int max_depth) {
  add_jack(scene, jack, frame);
  if (depth >= max_depth) return;
  for (double i = -0.5; i <= 0.5; i += 1.0) {
    for (double j = -0.5; j <= 0.5; j += 1.0) {
      for (double k = -0.5; k <= 0.5; k += 1.0) {
        const Mat4 child = scale_matrix(0.5) * (translate_matrix({i, j, k}) * frame);
        add_recursive_jack(scene, jack, child, depth + 1, max_depth);
      }
    }
  }
}

// The scene without the jacks: background, view, light, material.
Scene jacks_setting() {
  Scene scene;
  scene.background = {0.2f, 0.05f, 0.2f};  // dark purple
  set_spd_view(scene, {0.0, 0.0, -8.0}, {0.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, 25.0, 0.001, 256, 256);
  scene.lights.push_back(Light{{-10.0f, 3.0f, -20.0f}});

  // Pink: kd 0.7, ks 0.7, highlight 20 degrees, ior 1.
  scene.materials.push_back(spd_material({0.737, 0.561, 0.561}, 0.7, 0.7, 20.0, 0.0, 1.0));
  return scene;
}

// Everything turned -30 degrees about X, then -20 degrees about Y.
Mat4 root_frame() {
  return rotation_matrix(1, -20.0 * kSpdPi / 180.0) *
         (rotation_matrix(0, -30.0 * kSpdPi / 180.0) * Mat4{});
}

}  // namespace

Scene make_jacks(int size) {
  check_spd_size("jacks", size, kMinSize, kMaxSize);
  Scene scene = jacks_setting();
  add_recursive_jack(scene, local_jack(), root_frame(), 1, size);
  return scene;
}

Scene make_jacks_tessellated(int size, int resolution) {
  check_spd_size("jacks", size, kMinSize, kMaxSize);
  if (resolution < 1) {
    throw std::invalid_argument("tessellate: resolution " + std::to_string(resolution) +
                                " must be at least 1");
  }
  // (8^size - 1) / 7 jacks of 6 spheres (12 R^2 triangles) and 3 cones (8 R).
  const double jacks = (std::pow(8.0, size) - 1.0) / 7.0;
  const double r = resolution;
  const double wanted = jacks * (6.0 * 12.0 * r * r + 3.0 * 8.0 * r);
  if (wanted > double(kMaxTessellatedTriangles)) {
    throw std::invalid_argument(fmt::format(
        "tessellate {}: {:.0f} jacks x {:.0f} triangles make {:.0f} triangles, more than the {} "
        "supported; use a smaller -t or size",
        resolution, jacks, 6.0 * 12.0 * r * r + 3.0 * 8.0 * r, wanted, kMaxTessellatedTriangles));
  }
  Scene jack = local_jack();
  tessellate_scene(jack, resolution);
  Scene scene = jacks_setting();
  const auto patches = static_cast<std::size_t>(wanted);
  scene.shapes.reserve(patches);
  scene.vertices.reserve(3 * patches);
  scene.normals.reserve(3 * patches);
  add_recursive_jack(scene, jack, root_frame(), 1, size);
  return scene;
}

}  // namespace raynode::core::spd
