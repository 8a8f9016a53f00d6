// SPD "tetra": a recursive tetrahedral pyramid (Sierpinski tetrahedron), the
// scene of Glassner (1984) and Kay & Kajiya (1986); 4^size triangles, one
// light. Reproduces Eric Haines' SPD 3.14 tetra.c NFF output (default size 6).
#include <array>
#include <stdexcept>
#include <string>

#include "core/spd_generators.h"

namespace raynode::core::spd {
namespace {

constexpr int kMinSize = 1;
constexpr int kMaxSize = 11;  // 4^11 = 4.2M triangles (~250 MB as a Scene)

struct Point {
  double x, y, z;
};

// The four corners of the cube (centre c, half-width w) with x*y*z sign +1,
// in SPD's loop order (x outermost, then y, then z; each -1 then +1).
std::array<Point, 4> tetra_corners(const Point& c, double w) {
  std::array<Point, 4> out{};
  int n = 0;
  for (int sx = -1; sx <= 1; sx += 2) {
    for (int sy = -1; sy <= 1; sy += 2) {
      for (int sz = -1; sz <= 1; sz += 2) {
        if (sx * sy * sz == 1) out[n++] = {c.x + sx * w, c.y + sy * w, c.z + sz * w};
      }
    }
  }
  return out;
}

Vec3 to_vec3(const Point& p) {
  return {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)};
}

// Depth <= 1 writes one tetrahedron (faces 0 1 2, 3 2 1, 2 3 0, 1 0 3, all
// facing outward); deeper levels recurse into the four corner sub-cubes of
// half the width, in the same corner order.
void grow_tetra(Scene& scene, int depth, const Point& center, double half_width) {
  if (depth <= 1) {
    const std::array<Point, 4> corner = tetra_corners(center, half_width);
    static constexpr int kFaces[4][3] = {{0, 1, 2}, {3, 2, 1}, {2, 3, 0}, {1, 0, 3}};
    for (const auto& face : kFaces) {
      const Vec3 tri[3] = {to_vec3(corner[face[0]]), to_vec3(corner[face[1]]),
                           to_vec3(corner[face[2]])};
      scene.add_polygon(tri, 3);
    }
    return;
  }
  const double half = half_width / 2.0;
  for (const Point& sub : tetra_corners(center, half)) grow_tetra(scene, depth - 1, sub, half);
}

}  // namespace

Scene make_tetra(int size) {
  if (size < kMinSize || size > kMaxSize) {
    throw std::invalid_argument("tetra: size " + std::to_string(size) + " is out of range " +
                                std::to_string(kMinSize) + ".." + std::to_string(kMaxSize));
  }
  Scene scene;
  scene.background = {0.078f, 0.361f, 0.753f};
  scene.has_view = true;
  scene.view.from = {1.022846f, -3.177154f, -2.174512f};
  scene.view.at = {-0.004103f, -0.004103f, 0.216539f};
  scene.view.up = {-0.816497f, -0.816497f, 0.816497f};
  scene.view.angle = 45.0f;
  scene.view.hither = 1.0f;
  scene.view.width = scene.view.height = 512;
  scene.lights.push_back(Light{{2.0f, -18.0f, -5.0f}});

  // Red, diffuse only: SPD colour (1, 0.2, 0.2), kd 1, no highlight (shine 100000), ior 0.
  Material red;
  red.color = {1.0f, 0.2f, 0.2f};
  red.kd = 1.0f;
  red.ks = 0.0f;
  red.shine = 100000.0f;
  red.transmittance = 0.0f;
  red.ior = 0.0f;
  scene.materials.push_back(red);

  const std::size_t triangles = std::size_t{1} << (2 * size);
  scene.shapes.reserve(triangles);
  scene.vertices.reserve(3 * triangles);
  grow_tetra(scene, size, {0.0, 0.0, 0.0}, 1.0);
  return scene;
}

}  // namespace raynode::core::spd
