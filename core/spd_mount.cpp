// SPD "mount": a fractal mountain by midpoint displacement on a square grid
// (Carpenter's method, extended to squares), 2 * 4^size triangles, with a
// pyramid of four glass spheres in front of it; one light. Reproduces Eric
// Haines' SPD 3.14 mount.c NFF output (default size 6), including its
// original "faulty" hash, whose repetitions the SPD comments acknowledge and
// keep so that the database matches the November 1987 IEEE CG&A article.
//
// All geometry is computed in double, as SPD does, then stored as float.
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "core/spd_generators.h"

namespace raynode::core::spd {
namespace {

// SPD's hash shifts by (7 - size), so sizes above 7 are undefined in C.
constexpr int kMinSize = 1;
constexpr int kMaxSize = 7;
constexpr double kPi = 3.141592653589793;  // SPD's PI

constexpr double kFractalDimension = 2.2;  // between 2 and 3; sets the z variance
constexpr long kMountainNumber = 21;       // seed offset: another value, another mountain
constexpr double kCorner = -1.0;           // lower-left corner (x and y)
constexpr double kWidth = 2.0;             // side of the square

// The original mount.c hash of a grid point (a, b) at size factor c into a
// 16-bit seed (unsigned long arithmetic; c <= 7 keeps every shift legal).
long hash_seed(long a, long b, int c) {
  const std::uint64_t ua = static_cast<std::uint64_t>(a), ub = static_cast<std::uint64_t>(b);
  return static_cast<long>(((ua << (23 - c)) + (ub << (15 - c)) + (ua << (7 - c))) & 0xffffu);
}

// SPD's lib_gauss_rand: a Gaussian deviate from a seed, by the polar method
// on a linear congruential pair (Numerical Recipes GASDEV constants).
double gauss_rand(long seed) {
  constexpr long kM = 134456, kA = 8121, kC = 28411;
  long ix2 = seed;
  double v1, r;
  do {
    const long ix1 = (kC + ix2 * kA) % kM;
    ix2 = (kC + ix1 * kA) % kM;
    v1 = ix1 * 2.0 / kM - 1.0;
    const double v2 = ix2 * 2.0 / kM - 1.0;
    r = v1 * v1 + v2 * v2;
  } while (r >= 1.0);
  return v1 * std::sqrt(-2.0 * std::log(r) / r);
}

struct Mountain {
  Scene& scene;
  int size;          // SPD size factor (hash input)
  double num_pts;    // 2^size grid cells per side
  double roughness;  // rise per half side

  Vec3 point(int gx, int gy, double z) const {
    return {static_cast<float>(kCorner + gx * kWidth / num_pts),
            static_cast<float>(kCorner + gy * kWidth / num_pts), static_cast<float>(z)};
  }

  double displaced(double mid, double rise, int gx, int gy) const {
    return mid + rise * gauss_rand(kMountainNumber + hash_seed(gx, gy, size));
  }

  // The square of `width` cells at (x, y) with corner heights lower-left,
  // lower-right, upper-right, upper-left. Width 1 writes two triangles
  // (ll lr ur, ur ul ll); wider squares displace the four edge midpoints and
  // the centre and recurse into the quarters ll, lr, ur, ul.
  void grow(int width, int x, int y, double ll, double lr, double ur, double ul) {
    if (width == 1) {
      const Vec3 c[4] = {point(x, y, ll), point(x + 1, y, lr), point(x + 1, y + 1, ur),
                         point(x, y + 1, ul)};
      const Vec3 first[3] = {c[0], c[1], c[2]};
      const Vec3 second[3] = {c[2], c[3], c[0]};
      scene.add_polygon(first, 3);
      scene.add_polygon(second, 3);
      return;
    }
    const int half = width >> 1;
    const double rise = static_cast<double>(half) * kWidth / num_pts * roughness;
    const double lower = displaced((ll + lr) / 2.0, rise, x + half, y);
    const double right = displaced((lr + ur) / 2.0, rise, x + width, y + half);
    const double upper = displaced((ur + ul) / 2.0, rise, x + half, y + width);
    const double left = displaced((ul + ll) / 2.0, rise, x, y + half);
    const double middle = displaced((ll + lr + ur + ul) / 4.0, 1.4142136 * rise, x + half, y + half);
    grow(half, x, y, ll, lower, middle, left);
    grow(half, x + half, y, lower, lr, right, middle);
    grow(half, x + half, y + half, middle, right, ur, upper);
    grow(half, x, y + half, left, middle, upper, ul);
  }
};

// A tetrahedral pyramid of four spheres of radius r touching each other:
// the top one at centre + (0, 0, r sqrt(3/2)), then that offset tipped by
// acos(-1/3) about (1,1,0)/sqrt 2 and turned by 0, 120, 240 degrees about Z.
void add_sphere_pyramid(Scene& scene, const D3& center, double r) {
  auto add = [&](const D3& p) {
    scene.add_sphere(Sphere{{static_cast<float>(center.x + p.x), static_cast<float>(center.y + p.y),
                             static_cast<float>(center.z + p.z)},
                            static_cast<float>(r)});
  };
  const D3 top{0.0, 0.0, r * std::sqrt(3.0 / 2.0)};
  add(top);
  const double inv = 1.0 / std::sqrt(2.0);
  const D3 tipped = rotate(top, {inv, inv, 0.0}, std::acos(-1.0 / 3.0));
  for (int i = 0; i < 3; ++i) add(rotate(tipped, {0.0, 0.0, 1.0}, i * 2.0 * kPi / 3.0));
}

}  // namespace

Scene make_mount(int size) {
  if (size < kMinSize || size > kMaxSize) {
    throw std::invalid_argument("mount: size " + std::to_string(size) + " is out of range " +
                                std::to_string(kMinSize) + ".." + std::to_string(kMaxSize));
  }
  Scene scene;
  scene.background = {0.078f, 0.361f, 0.753f};
  scene.has_view = true;
  scene.view.from = {-1.6f, 1.6f, 1.7f};
  scene.view.at = {0.0f, 0.0f, 0.0f};
  scene.view.up = {0.0f, 0.0f, 1.0f};
  scene.view.angle = 45.0f;
  scene.view.hither = 0.01f;
  scene.view.width = scene.view.height = 512;
  scene.lights.push_back(Light{{-100.0f, -100.0f, 100.0f}});

  // Clear glass: kd 0.1, ks 0.1, highlight half-angle 6.7 degrees, T 0.9, ior 1.5.
  Material glass;
  glass.color = {1.0f, 1.0f, 1.0f};
  glass.kd = 0.1f;
  glass.ks = 0.1f;
  glass.shine = static_cast<float>(phong_power(6.7));
  glass.transmittance = 0.9f;
  glass.ior = 1.5f;
  scene.materials.push_back(glass);
  add_sphere_pyramid(scene, {-0.8, 0.8, 1.0}, 0.17);

  // Grey rock: diffuse only, ior 0.
  Material rock;
  rock.color = {0.5f, 0.45f, 0.35f};
  rock.kd = 1.0f;
  rock.ks = 0.0f;
  rock.shine = static_cast<float>(phong_power(0.0));
  rock.transmittance = 0.0f;
  rock.ior = 0.0f;
  scene.materials.push_back(rock);

  const int num_pts = 1 << size;
  const double ratio = 2.0 / std::exp(std::log(2.0) / (kFractalDimension - 1.0));
  const double roughness = std::sqrt(ratio * ratio - 1.0);
  const std::size_t triangles = 2 * static_cast<std::size_t>(num_pts) * num_pts;
  scene.shapes.reserve(scene.shapes.size() + triangles);
  scene.vertices.reserve(3 * triangles);
  Mountain{scene, size, static_cast<double>(num_pts), roughness}.grow(num_pts, 0, 0, 0.0, 0.0, 0.0,
                                                                       0.0);
  return scene;
}

}  // namespace raynode::core::spd
