// SPD "lattice" (Antonio Costa): a cubic lattice of shiny spheres joined to
// their neighbours by matte cylinders, seen from just outside one face; six
// lights. Size s gives (s+1)^3 spheres and 3 s (s+1)^2 cylinders (written as
// NFF cones), each preceded by its own `f` line: (s+1)^3 + 3 s (s+1)^2
// materials (s = 12: 2197 spheres, 6084 cylinders, 8281 materials).
// Reproduces Eric Haines' SPD 3.14 lattice.c NFF output (default size 12).
//
// All geometry is computed in double, as SPD does, then stored as float.
#include <cmath>

#include "core/spd_generators.h"

namespace raynode::core::spd {
namespace {

constexpr int kMinSize = 1;
constexpr int kMaxSize = 80;  // 531k spheres, 1.6M cylinders
constexpr double kSphereRatio = 1.0 / 4.0;     // sphere radius * size
constexpr double kCylinderRatio = 1.0 / 16.0;  // cylinder radius * size

}  // namespace

Scene make_lattice(int size) {
  check_spd_size("lattice", size, kMinSize, kMaxSize);
  const double s = size;
  const double cell = 1.0 / s;
  const double sphere_radius = kSphereRatio / s;
  const double cylinder_radius = kCylinderRatio / s;
  // Cylinders start just inside the spheres they join.
  const double inset = sphere_radius * (1.0 - std::sqrt(kCylinderRatio / kSphereRatio)) * 0.99;

  Scene scene;
  scene.background = {0.078f, 0.361f, 0.753f};
  const double view_x = ((size >> 1) + 0.5) * cell;
  const double half_cell = 1.0 / static_cast<double>(size << 1);
  set_spd_view(scene, {view_x, 1.0, 1.0 - half_cell}, {view_x, -1.0, -1.0 - half_cell},
               {0.2, 1.0, 0.0}, 60.0, 0.0, 512, 512);
  for (const D3& l : {D3{2.0, 0.5, 0.5}, D3{-1.0, 0.5, 0.5}, D3{0.5, 2.0, 0.5},
                      D3{0.5, -1.0, 0.5}, D3{0.5, 0.5, 2.0}, D3{0.5, 0.5, -1.0}}) {
    scene.lights.push_back(Light{as_vec3(l)});
  }

  // Shiny grey spheres: kd 0.5, ks 0.5, highlight 37 degrees. Cylinders
  // along X, Y, Z: red, green, blue, kd 0.99, no highlight.
  const Material sphere_material = spd_material({0.9, 0.9, 0.9}, 0.5, 0.5, 37.0, 0.0, 0.0);
  const Material axis_material[3] = {
      spd_material({0.9, 0.1, 0.1}, 0.99, 0.0, 0.0, 0.0, 0.0),
      spd_material({0.1, 0.9, 0.1}, 0.99, 0.0, 0.0, 0.0, 0.0),
      spd_material({0.1, 0.1, 0.9}, 0.99, 0.0, 0.0, 0.0, 0.0)};
  const float r_cyl = static_cast<float>(cylinder_radius);

  for (int x = 0; x <= size; ++x) {
    const double x0 = x / s;
    for (int y = 0; y <= size; ++y) {
      const double y0 = y / s;
      for (int z = 0; z <= size; ++z) {
        const double z0 = z / s;
        scene.materials.push_back(sphere_material);
        scene.add_sphere(Sphere{as_vec3({x0, y0, z0}), static_cast<float>(sphere_radius)});
        if (x != size) {
          scene.materials.push_back(axis_material[0]);
          scene.add_cone(Cone{as_vec3({x0 + inset, y0, z0}), r_cyl,
                              as_vec3({x0 + cell - inset, y0, z0}), r_cyl});
        }
        if (y != size) {
          scene.materials.push_back(axis_material[1]);
          scene.add_cone(Cone{as_vec3({x0, y0 + inset, z0}), r_cyl,
                              as_vec3({x0, y0 + cell - inset, z0}), r_cyl});
        }
        if (z != size) {
          scene.materials.push_back(axis_material[2]);
          scene.add_cone(Cone{as_vec3({x0, y0, z0 + inset}), r_cyl,
                              as_vec3({x0, y0, z0 + cell - inset}), r_cyl});
        }
      }
    }
  }
  return scene;
}

}  // namespace raynode::core::spd
