// SPD "sombrero" (Alexander Enzmann): a height field of the damped ripple
// cos(2 pi r) exp(-r) over [-4, 4]^2, written as triangles; one light. Size
// s samples a W x W grid, W = 32 * 2^(s-1), and gives 2 (W-1)^2 triangles
// (s = 1: 1922). Reproduces Eric Haines' SPD 3.14 sombrero.c NFF output
// (default size 1), including its quirk: the heights are sampled with step
// 8/W but placed on a grid of step 8/(W-1).
//
// Heights are float, as SPD stores them; the rest is double, then float.
#include <cmath>
#include <vector>

#include "core/spd_generators.h"

namespace raynode::core::spd {
namespace {

constexpr int kMinSize = 1;
constexpr int kMaxSize = 6;  // 1024 x 1024 samples, 2.1M triangles

// SPD's create_sombrero: row i, column j at y = -4 + i dy, x = -4 + j dx,
// both accumulated by repeated addition as SPD does.
std::vector<float> sample_heights(int width, int height) {
  const double x0 = -4.0, x1 = 4.0, y0 = -4.0, y1 = 4.0;
  const double a = 1.0, b = 1.0, c = 3.0;
  const double two_pi_a = 2.0 * 3.14159265358 * a;  // SPD's own truncated pi here
  const double dx = (x1 - x0) / width, dy = (y1 - y0) / height;
  std::vector<float> data(static_cast<std::size_t>(width) * height);
  double y = y0;
  for (int i = 0; i < height; ++i, y += dy) {
    double x = x0;
    for (int j = 0; j < width; ++j, x += dx) {
      const double r = std::sqrt(x * x + y * y);
      data[static_cast<std::size_t>(i) * width + j] =
          static_cast<float>(c * std::cos(two_pi_a * r) * std::exp(-b * r) / 3.0);
    }
  }
  return data;
}

}  // namespace

Scene make_sombrero(int size) {
  check_spd_size("sombrero", size, kMinSize, kMaxSize);
  Scene scene;
  scene.background = {0.078f, 0.361f, 0.753f};
  set_spd_view(scene, {0.0, 5.0, -8.0}, {0.0, 0.0, 0.0}, {0.0, 0.0, 1.0}, 40.0, 0.01, 512, 512);
  scene.lights.push_back(Light{{10.0f, 10.0f, -10.0f}});

  // Shiny red: kd 0.8, highlight 40 degrees, ior 1.
  scene.materials.push_back(spd_material({1.0, 0.1, 0.1}, 0.8, 0.0, 40.0, 0.0, 1.0));

  const int n = 32 << (size - 1);
  const std::vector<float> h = sample_heights(n, n);
  const auto height = [&](int i, int j) {
    return static_cast<double>(h[static_cast<std::size_t>(i) * n + j]);
  };
  // SPD's lib_output_polygon_height: x across columns, y = y0 + height, z
  // across rows; two triangles per cell.
  const double x0 = -4.0, x1 = 4.0, y0 = -3.0, z0 = -4.0, z1 = 4.0;
  const double dx = (x1 - x0) / (n - 1), dz = (z1 - z0) / (n - 1);
  const std::size_t triangles = 2 * static_cast<std::size_t>(n - 1) * (n - 1);
  scene.shapes.reserve(triangles);
  scene.vertices.reserve(3 * triangles);
  for (int i = 0; i < n - 1; ++i) {
    for (int j = 0; j < n - 1; ++j) {
      const Vec3 corner = as_vec3({x0 + j * dx, y0 + height(i, j), z0 + i * dz});
      const Vec3 far = as_vec3({x0 + (j + 1) * dx, y0 + height(i + 1, j + 1), z0 + (i + 1) * dz});
      const Vec3 right = as_vec3({x0 + (j + 1) * dx, y0 + height(i, j + 1), z0 + i * dz});
      const Vec3 up = as_vec3({x0 + j * dx, y0 + height(i + 1, j), z0 + (i + 1) * dz});
      const Vec3 first[3] = {corner, far, right};
      const Vec3 second[3] = {corner, up, far};
      scene.add_polygon(first, 3);
      scene.add_polygon(second, 3);
    }
  }
  return scene;
}

}  // namespace raynode::core::spd
