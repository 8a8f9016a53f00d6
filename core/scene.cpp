#include "core/scene.h"

#include <cmath>

namespace raynode::core {

std::uint32_t Scene::current_material() {
  if (materials.empty()) materials.push_back(Material{});
  return static_cast<std::uint32_t>(materials.size() - 1);
}

void Scene::add_polygon(const Vec3* verts, std::uint32_t n) {
  Shape s;
  s.kind = ShapeKind::kPolygon;
  s.material = current_material();
  s.first = static_cast<std::uint32_t>(vertices.size());
  s.count = n;
  vertices.insert(vertices.end(), verts, verts + n);
  shapes.push_back(s);
}

void Scene::add_patch(const Vec3* verts, const Vec3* vertex_normals, std::uint32_t n) {
  Shape s;
  s.kind = ShapeKind::kPatch;
  s.material = current_material();
  s.first = static_cast<std::uint32_t>(vertices.size());
  s.count = n;
  s.first_normal = static_cast<std::uint32_t>(normals.size());
  vertices.insert(vertices.end(), verts, verts + n);
  normals.insert(normals.end(), vertex_normals, vertex_normals + n);
  shapes.push_back(s);
}

void Scene::add_sphere(const Sphere& sp) {
  Shape s;
  s.kind = ShapeKind::kSphere;
  s.material = current_material();
  s.first = static_cast<std::uint32_t>(spheres.size());
  s.count = 1;
  spheres.push_back(sp);
  shapes.push_back(s);
}

void Scene::add_cone(const Cone& c) {
  Shape s;
  s.kind = ShapeKind::kCone;
  s.material = current_material();
  s.first = static_cast<std::uint32_t>(cones.size());
  s.count = 1;
  cones.push_back(c);
  shapes.push_back(s);
}

SceneCounts Scene::counts() const {
  SceneCounts c;
  for (const Shape& s : shapes) {
    switch (s.kind) {
      case ShapeKind::kPolygon: ++c.polygons; break;
      case ShapeKind::kPatch: ++c.patches; break;
      case ShapeKind::kSphere: ++c.spheres; break;
      case ShapeKind::kCone: ++c.cones; break;
    }
  }
  c.lights = lights.size();
  c.materials = materials.size();
  c.dropped_degenerate = dropped_degenerate;
  return c;
}

Bounds3 Scene::bounds() const {
  Bounds3 b;
  for (const Shape& s : shapes) {
    switch (s.kind) {
      case ShapeKind::kPolygon:
      case ShapeKind::kPatch:
        for (std::uint32_t i = 0; i < s.count; ++i) b.extend(vertices[s.first + i]);
        break;
      case ShapeKind::kSphere: {
        const Sphere& sp = spheres[s.first];
        const float r = std::fabs(sp.radius);
        b.extend(Bounds3{sp.center - Vec3{r, r, r}, sp.center + Vec3{r, r, r}});
        break;
      }
      case ShapeKind::kCone: {
        const Cone& c = cones[s.first];
        const float rb = std::fabs(c.base_radius), ra = std::fabs(c.apex_radius);
        b.extend(Bounds3{c.base - Vec3{rb, rb, rb}, c.base + Vec3{rb, rb, rb}});
        b.extend(Bounds3{c.apex - Vec3{ra, ra, ra}, c.apex + Vec3{ra, ra, ra}});
        break;
      }
    }
  }
  return b;
}

bool is_degenerate_polygon(const Vec3* v, std::uint32_t n, float rel_eps) {
  if (n < 3) return true;
  // Newell's method: twice the signed area vector, exact for planar polygons.
  double nx = 0, ny = 0, nz = 0, longest2 = 0;
  for (std::uint32_t i = 0; i < n; ++i) {
    const Vec3& a = v[i];
    const Vec3& b = v[(i + 1) % n];
    nx += (double(a.y) - b.y) * (double(a.z) + b.z);
    ny += (double(a.z) - b.z) * (double(a.x) + b.x);
    nz += (double(a.x) - b.x) * (double(a.y) + b.y);
    const double ex = double(b.x) - a.x, ey = double(b.y) - a.y, ez = double(b.z) - a.z;
    longest2 = std::max(longest2, ex * ex + ey * ey + ez * ez);
  }
  const double area2 = std::sqrt(nx * nx + ny * ny + nz * nz);
  return !(area2 > double(rel_eps) * longest2);
}

}  // namespace raynode::core
