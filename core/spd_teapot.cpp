// SPD teapot: the Utah teapot tessellated into smooth-shaded triangles,
// standing on a checkerboard, as Eric Haines' Standard Procedural Databases
// 3.14 program `teapot -s N` writes it in NFF (src/teapot.c and the library's
// lib_output_color / lib_output_viewpoint, read for the facts; this is
// raynode's own code).
//
// Place in the data flow: make_spd_scene("teapot", N) (spd.cpp) -> here ->
// Scene, equal (numbers within SPD's %g printing) to read_nff of the file the
// SPD program writes. The Bezier data is compiled in (spd_teapot_data.inc);
// nothing is read at run time.
//
// What the SPD program does, and so what this file reproduces:
//  * background 0.078 0.361 0.753 ("UNC sky blue"); view from (4.86, 7.2,
//    5.4) at the origin, up +Z, 45 degrees, hither 1, 512 x 512; two lights
//    with no colour.
//  * Checkerboard: N x N squares covering [-4, 4]^2 at z = 0, as `p` quads.
//    First a white material and every square with (s + t) odd, then a grey
//    one and every square with (s + t) even, both loops s-major.
//  * Teapot: one orange material, then for each of the 32 patches, for each
//    cell (s, t) of an N x N parameter grid (s-major), two triangles
//    (s,t)-(s,t+1)-(s+1,t+1) and (s+1,t+1)-(s+1,t)-(s,t), as `pp` with the
//    unit normal dP/dt x dP/ds at each vertex. Everything is computed in
//    double and stored as float.
//  * Cusps: a triangle with more than one vertex on the z axis (|x|, |y| <=
//    1e-4) is dropped (lid knob and bottom centre); where exactly one vertex
//    is on the axis its normal is set to +Z (z > 1.5, lid) or -Z (bottom).
//    Hence 64 N^2 - 8 N triangles.
//  * SPD evaluates the patches through power-basis matrices M G M^T; the
//    Bernstein form used here is the same polynomial (differences ~1e-16).
//  * Orientation: from size 6 (SPD's default) up, every vertex normal lies on
//    the side of its triangle's (v1-v0)x(v2-v0); at sizes 2..5 a few coarse
//    triangles on the spout tip and the lid knob disagree (28 normals at size
//    2), in SPD's own output too. The teapot must be rendered double-sided.
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/spd_generators.h"

namespace raynode::core::spd {
namespace {

#include "core/spd_teapot_data.inc"

/// Size factors accepted. SPD itself flags size 1 as unsupported (its output
/// then holds zero-area triangles). The upper bound is ours: size 64 gives
/// 261,632 triangles (about 20 MB of scene), well past the sizes SPD's
/// own table lists (up to 12), and stops a typo from exhausting memory.
constexpr int kMinSize = 2;
constexpr int kMaxSize = 64;

/// Highest point of the teapot's bottom; an axis vertex above it is the lid
/// knob (SPD's test, teapot.c check_for_cusp).
constexpr double kCuspSplitHeight = 1.5;
/// A vertex is "on the z axis" when |x| and |y| are both within this.
constexpr double kAxisTolerance = 1e-4;

/// Double-precision vector: SPD computes in double and prints %g; we store
/// floats only at the end.
struct DVec3 {
  double x = 0.0, y = 0.0, z = 0.0;
};

DVec3 operator+(const DVec3& a, const DVec3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
DVec3 operator*(double s, const DVec3& a) { return {s * a.x, s * a.y, s * a.z}; }
DVec3 cross(const DVec3& a, const DVec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
/// Unit vector along a; a zero vector is returned unchanged (as SPD's
/// lib_normalize_vector does; only cusp vertices have one, and those are
/// overwritten or dropped).
DVec3 normalized(const DVec3& a) {
  const double len = std::sqrt(a.x * a.x + a.y * a.y + a.z * a.z);
  return len > 0.0 ? (1.0 / len) * a : a;
}
Vec3 to_float(const DVec3& a) {
  return {static_cast<float>(a.x), static_cast<float>(a.y), static_cast<float>(a.z)};
}

/// NFF material as SPD writes it: `f r g b kd ks shine T ior`. SPD's teapot
/// passes ior 0 for its opaque surfaces, and the file carries that 0.
Material spd_material(Vec3 color, double kd, double ks, double half_angle_deg) {
  Material m;
  m.color = color;
  m.kd = static_cast<float>(kd);
  m.ks = static_cast<float>(ks);
  m.shine = static_cast<float>(phong_power(half_angle_deg));
  m.transmittance = 0.0f;
  m.ior = 0.0f;
  return m;
}

/// Cubic Bernstein basis B0..B3 at u, and its derivative.
void bernstein(double u, double b[4], double db[4]) {
  const double v = 1.0 - u;
  b[0] = v * v * v;
  b[1] = 3.0 * u * v * v;
  b[2] = 3.0 * u * u * v;
  b[3] = u * u * u;
  db[0] = -3.0 * v * v;
  db[1] = 3.0 * v * v - 6.0 * u * v;
  db[2] = 6.0 * u * v - 3.0 * u * u;
  db[3] = 3.0 * u * u;
}

struct SurfacePoint {
  DVec3 position;
  DVec3 normal;  ///< unit, or zero at a cusp
};

/// Point and normal of Bezier patch `patch` at (s, t), s along the control
/// grid's rows, t along its columns. Normal = normalize(dP/dt x dP/ds), the
/// outward side in SPD's convention.
SurfacePoint eval_patch(int patch, double s, double t) {
  double bs[4], dbs[4], bt[4], dbt[4];
  bernstein(s, bs, dbs);
  bernstein(t, bt, dbt);
  DVec3 p, dp_ds, dp_dt;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) {
      const double* cv = kTeapotVertices[kTeapotPatches[patch][4 * r + c]];
      const DVec3 g{cv[0], cv[1], cv[2]};
      p = p + (bs[r] * bt[c]) * g;
      dp_ds = dp_ds + (dbs[r] * bt[c]) * g;
      dp_dt = dp_dt + (bs[r] * dbt[c]) * g;
    }
  }
  return {p, normalized(cross(dp_dt, dp_ds))};
}

/// SPD's cusp rule for one triangle: false when more than one vertex lies on
/// the z axis (a zero-area sliver at the lid knob or the bottom centre);
/// with exactly one such vertex, its normal is set straight up (lid) or
/// down (bottom), since the surface normal there is undefined.
bool fix_cusp(SurfacePoint tri[3]) {
  int on_axis = 0;
  int which = -1;
  for (int i = 0; i < 3; ++i) {
    if (std::fabs(tri[i].position.x) <= kAxisTolerance &&
        std::fabs(tri[i].position.y) <= kAxisTolerance) {
      ++on_axis;
      which = i;
    }
  }
  if (on_axis > 1) return false;
  if (on_axis == 1) {
    const double up = tri[which].position.z > kCuspSplitHeight ? 1.0 : -1.0;
    tri[which].normal = {0.0, 0.0, up};
  }
  return true;
}

/// One checkerboard square (s, t) of an n x n board over [-4, 4]^2, z = 0,
/// counter-clockwise seen from +Z starting at its (low x, low y) corner.
void add_square(Scene& scene, int n, int s, int t) {
  auto coord = [n](int step) { return 4.0 * (2.0 * static_cast<double>(step) / n - 1.0); };
  const float x0 = static_cast<float>(coord(s)), x1 = static_cast<float>(coord(s + 1));
  const float y0 = static_cast<float>(coord(t)), y1 = static_cast<float>(coord(t + 1));
  const Vec3 quad[4] = {{x0, y0, 0.0f}, {x1, y0, 0.0f}, {x1, y1, 0.0f}, {x0, y1, 0.0f}};
  scene.add_polygon(quad, 4);
}

void add_checkerboard(Scene& scene, int n) {
  // White squares where (s + t) is odd first, then grey where it is even.
  scene.materials.push_back(spd_material({1.0f, 1.0f, 1.0f}, 0.5, 0.5, 30.0));
  for (int s = 0; s < n; ++s)
    for (int t = 0; t < n; ++t)
      if ((s + t) % 2 == 1) add_square(scene, n, s, t);
  scene.materials.push_back(spd_material({0.5f, 0.5f, 0.5f}, 0.5, 0.5, 30.0));
  for (int s = 0; s < n; ++s)
    for (int t = 0; t < n; ++t)
      if ((s + t) % 2 == 0) add_square(scene, n, s, t);
}

void add_teapot(Scene& scene, int n) {
  scene.materials.push_back(spd_material({1.0f, 0.5f, 0.1f}, 0.75, 0.25, 37.0));
  // Corners of a grid cell as (ds, dt) offsets, in SPD's order; triangle k
  // uses corners 2k, 2k+1, 2k+2 (mod 4).
  constexpr int kCorner[4][2] = {{0, 0}, {0, 1}, {1, 1}, {1, 0}};
  for (int patch = 0; patch < kTeapotPatchCount; ++patch) {
    for (int s = 0; s < n; ++s) {
      for (int t = 0; t < n; ++t) {
        for (int tri_index = 0; tri_index < 2; ++tri_index) {
          SurfacePoint tri[3];
          for (int v = 0; v < 3; ++v) {
            const int* corner = kCorner[(2 * tri_index + v) % 4];
            // Divide (not multiply by 1/n), as SPD does, so grid parameters match.
            tri[v] = eval_patch(patch, static_cast<double>(s + corner[0]) / n,
                                static_cast<double>(t + corner[1]) / n);
          }
          if (!fix_cusp(tri)) continue;
          Vec3 verts[3], normals[3];
          for (int v = 0; v < 3; ++v) {
            verts[v] = to_float(tri[v].position);
            normals[v] = to_float(tri[v].normal);
          }
          scene.add_patch(verts, normals, 3);
        }
      }
    }
  }
}

}  // namespace

/// The scene `teapot -s size` writes. size in [2, 64]; throws
/// std::invalid_argument outside (size 1 is SPD's "unsupported" size).
Scene make_teapot(int size) {
  if (size < kMinSize) {
    throw std::invalid_argument(
        "teapot: size " + std::to_string(size) + " is not supported (minimum " +
        std::to_string(kMinSize) +
        "; SPD flags size 1 as unsupported: it emits zero-area triangles)");
  }
  if (size > kMaxSize) {
    throw std::invalid_argument("teapot: size " + std::to_string(size) +
                                " is too large (maximum " + std::to_string(kMaxSize) + ", " +
                                "i.e. " + std::to_string(64 * kMaxSize * kMaxSize - 8 * kMaxSize) +
                                " triangles)");
  }
  Scene scene;
  scene.background = {0.078f, 0.361f, 0.753f};
  scene.has_view = true;
  scene.view.from = {4.86f, 7.2f, 5.4f};
  scene.view.at = {0.0f, 0.0f, 0.0f};
  scene.view.up = {0.0f, 0.0f, 1.0f};
  scene.view.angle = 45.0f;
  scene.view.hither = 1.0f;
  scene.view.width = 512;
  scene.view.height = 512;
  scene.lights.push_back(Light{{-3.1f, 9.8f, 12.1f}});
  scene.lights.push_back(Light{{11.3f, 5.1f, 8.8f}});

  const auto n = static_cast<std::size_t>(size);
  scene.shapes.reserve(n * n + 64 * n * n);
  scene.vertices.reserve(4 * n * n + 3 * 64 * n * n);
  scene.normals.reserve(3 * 64 * n * n);

  add_checkerboard(scene, size);
  add_teapot(scene, size);
  return scene;
}

}  // namespace raynode::core::spd
