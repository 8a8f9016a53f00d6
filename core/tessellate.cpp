// tessellate_scene: SPD's -t R polygonalisation of curved primitives.
//
// Sphere (SPD lib_output_polygon_sphere): a cube projected onto the sphere.
// Each face is an R x R grid whose points are normalize(x_u cross y_v), with
// x_u = +X turned about Y and y_v = +Y turned about X by pi/4 (2k/R - 1); the
// grid starts on the -X face and is carried to the next face by an in-place
// cube-face rotation; every cell gives the triangles (p[u][v], p[u][v+1],
// p[u+1][v+1]) and (p[u+1][v+1], p[u+1][v], p[u][v]), with the unit point as
// the vertex normal. 12 R^2 triangles.
//
// Cone/cylinder (SPD lib_output_polygon_cylcone): a strip of 4R quads about
// the axis, each written as two triangles, starting from the radius direction
// axis x (0,0,1) (or axis x (1,0,0) when the axis is within 1e-6 of Z), with
// the true cone normal at each vertex. 8R triangles.
//
// Every number is computed in double from the float scene, as SPD computes
// in double, then stored as float.
#include <fmt/core.h>

#include <array>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/spd.h"
#include "core/spd_generators.h"
#include "core/stop.h"

namespace raynode::core {
namespace {

using spd::D3;
using spd::rotate;

constexpr double kPi = 3.141592653589793;  // SPD's PI
constexpr double kParallelEpsilon = 1e-6;  // SPD's EPSILON2 (def.h)

D3 to_d3(const Vec3& v) { return {v.x, v.y, v.z}; }
Vec3 to_vec3(const D3& p) {
  return {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)};
}
D3 operator+(const D3& a, const D3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
D3 operator-(const D3& a, const D3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
D3 operator*(const D3& a, double s) { return {a.x * s, a.y * s, a.z * s}; }
D3 cross(const D3& a, const D3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
double norm(const D3& a) { return std::sqrt(a.x * a.x + a.y * a.y + a.z * a.z); }
// SPD's lib_normalize_vector: leaves a zero vector alone; returns the length.
double normalize_in_place(D3& a) {
  const double len = norm(a);
  if (len > 0.0) a = {a.x / len, a.y / len, a.z / len};
  return len;
}

// SPD's lib_rotate_cube_face(vec, Z_AXIS, face): a quarter turn that carries
// the grid to the next cube face.
void rotate_cube_face(D3& v, int face) {
  switch ((face + 2) % 3) {
    case 0: v = {-v.y, v.x, v.z}; break;
    case 1: v = {v.x, -v.z, v.y}; break;
    default: v = {-v.z, v.y, v.x}; break;
  }
}

// Unit points of the projected cube, per face: [face][u][v], (R+1)^2 each.
struct CubeSphereGrid {
  int r;
  std::vector<D3> points;  // 6 * (r+1) * (r+1)

  explicit CubeSphereGrid(int resolution) : r(resolution), points(6 * (r + 1) * (r + 1)) {
    std::vector<D3> x_axis(r + 1), y_axis(r + 1);
    for (int k = 0; k <= r; ++k) {
      const double angle = (kPi / 4.0) * (2.0 * k / r - 1.0);
      x_axis[k] = rotate({1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, angle);
      y_axis[k] = rotate({0.0, 1.0, 0.0}, {1.0, 0.0, 0.0}, angle);
    }
    std::vector<D3> grid((r + 1) * (r + 1));
    for (int u = 0; u <= r; ++u) {
      for (int v = 0; v <= r; ++v) {
        D3 p = cross(x_axis[u], y_axis[v]);
        normalize_in_place(p);
        grid[u * (r + 1) + v] = p;
      }
    }
    for (int face = 0; face < 6; ++face) {
      for (D3& p : grid) rotate_cube_face(p, face);
      std::copy(grid.begin(), grid.end(), points.begin() + face * grid.size());
    }
  }

  const D3& at(int face, int u, int v) const {
    return points[(face * (r + 1) + u) * (r + 1) + v];
  }
};

void append_patch(Scene& out, std::uint32_t material, const std::array<D3, 3>& verts,
                  const std::array<D3, 3>& normals) {
  Shape s;
  s.kind = ShapeKind::kPatch;
  s.material = material;
  s.first = static_cast<std::uint32_t>(out.vertices.size());
  s.count = 3;
  s.first_normal = static_cast<std::uint32_t>(out.normals.size());
  for (int i = 0; i < 3; ++i) {
    out.vertices.push_back(to_vec3(verts[i]));
    out.normals.push_back(to_vec3(normals[i]));
  }
  out.shapes.push_back(s);
}

void tessellate_sphere(Scene& out, std::uint32_t material, const Sphere& sphere,
                       const CubeSphereGrid& grid) {
  const D3 c = to_d3(sphere.center);
  const double radius = sphere.radius;
  const int r = grid.r;
  for (int face = 0; face < 6; ++face) {
    for (int u = 0; u < r; ++u) {
      if (stop_requested()) throw_if_stopped(fmt::format("tessellating the scene (-t {})", r));
      for (int v = 0; v < r; ++v) {
        const D3& p00 = grid.at(face, u, v);
        const D3& p01 = grid.at(face, u, v + 1);
        const D3& p11 = grid.at(face, u + 1, v + 1);
        const D3& p10 = grid.at(face, u + 1, v);
        const std::array<D3, 3> first = {p00, p01, p11};
        const std::array<D3, 3> second = {p11, p10, p00};
        for (const auto& tri : {first, second}) {
          append_patch(out, material, {tri[0] * radius + c, tri[1] * radius + c, tri[2] * radius + c},
                       tri);
        }
      }
    }
  }
}

void tessellate_cone(Scene& out, std::uint32_t material, const Cone& cone, int r) {
  const D3 base = to_d3(cone.base), apex = to_d3(cone.apex);
  const double base_r = cone.base_radius, apex_r = cone.apex_radius;
  const D3 axis = apex - base;
  D3 unit_axis = axis;
  const double height = normalize_in_place(unit_axis);

  D3 start_dir = cross(axis, {0.0, 0.0, 1.0});
  if (std::fabs(normalize_in_place(start_dir)) < kParallelEpsilon) {
    start_dir = cross(axis, {1.0, 0.0, 0.0});
    normalize_in_place(start_dir);
  }
  const D3 base_radius = start_dir * base_r;
  const D3 apex_radius = start_dir * apex_r;
  D3 start_norm = start_dir;
  if (base_r != apex_r) {  // a cone: tilt the radial direction by the slope
    start_norm = start_dir * height + unit_axis * (base_r - apex_r);
    normalize_in_place(start_norm);
  }

  // Each step writes (new apex, old apex, old base) and (new base, new apex,
  // old base): the quad between the previous and the next generator line.
  std::array<D3, 3> vert = {D3{}, apex + apex_radius, base + base_radius};
  std::array<D3, 3> nrm = {D3{}, start_norm, start_norm};
  const double delta = 2.0 * kPi / static_cast<double>(4 * r);
  double angle = delta;
  for (int i = 1; i <= 4 * r; ++i, angle += delta) {
    vert[0] = rotate(apex_radius, unit_axis, angle) + apex;
    nrm[0] = rotate(start_norm, unit_axis, angle);
    append_patch(out, material, vert, nrm);
    vert[1] = vert[0];
    nrm[1] = nrm[0];
    vert[0] = rotate(base_radius, unit_axis, angle) + base;
    append_patch(out, material, vert, nrm);
    vert[2] = vert[0];
    nrm[2] = nrm[0];
  }
}

}  // namespace

void tessellate_scene(Scene& scene, int resolution) {
  if (resolution < 1) {
    throw std::invalid_argument("tessellate: resolution " + std::to_string(resolution) +
                                " must be at least 1");
  }
  std::size_t spheres = 0, cones = 0;
  for (const Shape& s : scene.shapes) {
    spheres += s.kind == ShapeKind::kSphere;
    cones += s.kind == ShapeKind::kCone;
  }
  if (spheres == 0 && cones == 0) return;

  const std::size_t r = static_cast<std::size_t>(resolution);
  // Counted in double first: with R up to INT_MAX, 12 R^2 alone passes 2^64.
  const double wanted = double(spheres) * 12 * double(r) * double(r) + double(cones) * 8 * double(r);
  if (wanted > double(kMaxTessellatedTriangles))
    throw std::invalid_argument(fmt::format(
        "tessellate {}: {} spheres x {:.0f} triangles and {} cones x {} make {:.0f} triangles, more than the {} "
        "supported (~{} GiB of primitive records); use a smaller -t or scene",
        resolution, spheres, 12 * double(r) * double(r), cones, 8 * r, wanted, kMaxTessellatedTriangles,
        (kMaxTessellatedTriangles * 64) >> 30));
  const std::size_t new_patches = spheres * 12 * r * r + cones * 8 * r;  // <= 2^25 here
  Scene out;
  out.view = scene.view;
  out.has_view = scene.has_view;
  out.background = scene.background;
  out.lights = std::move(scene.lights);
  out.materials = std::move(scene.materials);
  out.dropped_degenerate = scene.dropped_degenerate;
  out.shapes.reserve(scene.shapes.size() - spheres - cones + new_patches);
  out.vertices.reserve(scene.vertices.size() + 3 * new_patches);
  out.normals.reserve(scene.normals.size() + 3 * new_patches);

  const CubeSphereGrid grid(resolution);
  const std::string doing = fmt::format("tessellating the scene (-t {})", resolution);
  std::size_t work = 0;  // shapes and triangles made since the last stop poll
  for (const Shape& s : scene.shapes) {
    work += 1 + (s.kind == ShapeKind::kSphere ? 12 * r * r : s.kind == ShapeKind::kCone ? 8 * r : 0);
    if (work >= 4096) {
      work = 0;
      throw_if_stopped(doing);
    }
    switch (s.kind) {
      case ShapeKind::kPolygon:
      case ShapeKind::kPatch: {
        Shape copy = s;
        copy.first = static_cast<std::uint32_t>(out.vertices.size());
        out.vertices.insert(out.vertices.end(), scene.vertices.begin() + s.first,
                            scene.vertices.begin() + s.first + s.count);
        if (s.kind == ShapeKind::kPatch) {
          copy.first_normal = static_cast<std::uint32_t>(out.normals.size());
          out.normals.insert(out.normals.end(), scene.normals.begin() + s.first_normal,
                             scene.normals.begin() + s.first_normal + s.count);
        }
        out.shapes.push_back(copy);
        break;
      }
      case ShapeKind::kSphere:
        tessellate_sphere(out, s.material, scene.spheres[s.first], grid);
        break;
      case ShapeKind::kCone:
        tessellate_cone(out, s.material, scene.cones[s.first], resolution);
        break;
    }
  }
  scene = std::move(out);
}

}  // namespace raynode::core
