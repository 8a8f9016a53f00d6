// SPD "shells": a sea shell by Pickover's method (IEEE CG&A, November 1989),
// a logarithmic spiral of overlapping spheres that grow from tiny to large;
// one light. A study of a realistic yet pathological database (many tiny,
// overlapping primitives). Size s gives steps = 180 * 2^s and the spheres
// i = -(2 steps / 3) .. steps / 3 (C integer division), steps + 1 of them
// when steps is a multiple of 3 (s = 5: 5761). Reproduces Eric Haines' SPD
// 3.14 shells.c NFF output with its default shape parameters (default
// size 5).
//
// All geometry is computed in double, as SPD does, then stored as float.
#include <cmath>

#include "core/spd_generators.h"

namespace raynode::core::spd {
namespace {

constexpr int kMinSize = 1;
constexpr int kMaxSize = 14;  // 2.9M spheres

// Pickover's shell parameters as SPD's defaults set them (-g, -a, -b, -e).
constexpr double kGamma = 1.0;     // radius divisor
constexpr double kAlpha = 0.0;     // > 0: z = alpha * angle instead of beta * r
constexpr double kBeta = -2.0;     // z = beta * r
constexpr double kExponent = 0.15;  // r = k exp(exponent * angle)
constexpr double kRelativeSize = 1.0;  // k

}  // namespace

Scene make_shells(int size) {
  check_spd_size("shells", size, kMinSize, kMaxSize);
  Scene scene;
  scene.background = {0.078f, 0.361f, 0.753f};
  set_spd_view(scene, {-6.0, -60.0, 35.0}, {0.0, 8.0, -15.0}, {0.0, 0.0, 1.0}, 45.0, 0.5, 512,
               512);
  scene.lights.push_back(Light{{-100.0f, -100.0f, 100.0f}});

  // Pearly orange: kd 0.8, ks 0.2, highlight 10 degrees, ior 1.
  scene.materials.push_back(spd_material({1.0, 0.8, 0.4}, 0.8, 0.2, 10.0, 0.0, 1.0));

  const long steps = static_cast<long>(180.0 * std::pow(2.0, static_cast<double>(size)));
  scene.shapes.reserve(static_cast<std::size_t>(steps) + 1);
  scene.spheres.reserve(static_cast<std::size_t>(steps) + 1);
  for (long i = -steps * 2 / 3; i <= steps / 3; ++i) {
    const double angle = 3.0 * 6.0 * kSpdPi * static_cast<double>(i) / static_cast<double>(steps);
    const double r = kRelativeSize * std::exp(kExponent * angle);
    const double z = kAlpha > 0.0 ? kAlpha * angle : kBeta * r;
    scene.add_sphere(
        Sphere{as_vec3({r * std::sin(angle), r * std::cos(angle), z}), static_cast<float>(r / kGamma)});
  }
  return scene;
}

}  // namespace raynode::core::spd
