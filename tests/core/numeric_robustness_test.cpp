// Numerical robustness of the core at any scale: the error-bounded spawn of
// secondary rays (spawn.h), the triangle test's t > error-bound rule, the
// stable cone quadratic, normals and the view's 'up' without overflow, and
// the scene transform. Each case failed before the change it covers.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/camera.h"
#include "core/database.h"
#include "core/intersect.h"
#include "core/nff.h"
#include "core/scene_transform.h"
#include "core/spawn.h"

using namespace raynode::core;

namespace {

Primitive triangle(const Vec3& a, const Vec3& b, const Vec3& c) {
  Primitive p;
  p.kind = PrimitiveKind::kTriangle;
  const Vec3 v[3] = {a, b, c};
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) p.data[3 * i + k] = v[i][k];
  return p;
}

bool hits_triangle(const Ray& r, const Primitive& p, float& t) {
  TriangleHit h;
  if (!intersect_triangle(r, WatertightRay(r.direction), p.vertex(0), p.vertex(1), p.vertex(2), kInfinity, h))
    return false;
  t = h.t;
  return true;
}

}  // namespace

TEST_CASE("spawn: a reflected ray leaves a tilted triangle without hitting it, from 1e-6 to 1e6 scale and far away") {
  int rays = 0;
  for (double scale : {1e-6, 1e-3, 1.0, 1e3, 1e6})
    for (double shift : {0.0, 1e2, 1e4}) {
      const auto pt = [&](double x, double y, double z) {
        return Vec3{float(x * scale + shift), float(y * scale - shift), float(z * scale + 0.5 * shift)};
      };
      const Primitive tri = triangle(pt(0, 0, 0.1), pt(1, 0.2, 0.3), pt(0.3, 1, 0.7));
      const Vec3 n = geometric_normal(tri, tri.vertex(0));
      for (int i = 1; i < 40; ++i)
        for (int j = 1; j < 40 - i; ++j) {
          const float u = float(i) / 40.0f, v = float(j) / 40.0f;
          const Vec3 target = tri.vertex(0) * (1 - u - v) + tri.vertex(1) * u + tri.vertex(2) * v;
          const Vec3 eye = target + n * float(2 * scale) + Vec3{0.3f, -0.2f, 0.1f} * float(scale);
          const Ray in{eye, target - eye, 0.0f, kInfinity};
          float t = 0;
          if (!hits_triangle(in, tri, t)) continue;
          Hit hit;
          hit.t = t;
          hit.primitive = 0;
          TriangleHit th;
          intersect_triangle(in, WatertightRay(in.direction), tri.vertex(0), tri.vertex(1), tri.vertex(2), kInfinity, th);
          hit.u = th.u;
          hit.v = th.v;
          const HitPoint hp = hit_point(tri, in, hit);
          const Vec3 nf = dot(n, in.direction) < 0 ? n : -n;
          const Vec3 d = normalize(in.direction);
          const Ray out{offset_ray_origin(hp, nf), d - nf * (2 * dot(d, nf)), 0.0f, kInfinity};
          const Ray through{offset_ray_origin(hp, -nf), d, 0.0f, kInfinity};
          float t2 = 0;
          CAPTURE(scale);
          CAPTURE(shift);
          CHECK_FALSE(hits_triangle(out, tri, t2));      // no self-hit on the way out
          CHECK_FALSE(hits_triangle(through, tri, t2));  // nor on the way through
          // The offset is a few float spacings of the vertices' coordinates, not a fixed length.
          const float mag = std::max({max_component(abs(tri.vertex(0))), max_component(abs(tri.vertex(1))),
                                      max_component(abs(tri.vertex(2)))});
          const float spacing = std::ldexp(1.0f, std::ilogb(mag) - 23);
          CHECK(length(out.origin - hp.p) <= 64 * spacing);
          ++rays;
        }
    }
  CHECK(rays > 5000);
}

TEST_CASE("spawn: rays leaving a sphere from outside and inside never hit it again, at radius 1e-6 .. 1e6") {
  for (double r : {1e-6, 1.0, 1e6}) {
    Primitive s;
    s.kind = PrimitiveKind::kSphere;
    s.data[0] = float(3 * r);
    s.data[1] = float(-r);
    s.data[2] = float(r / 3);
    s.data[3] = float(r);
    for (int i = 0; i < 200; ++i) {
      const double a = 0.1 + i * 0.031, b = 0.05 + i * 0.017;
      const Vec3 dir{float(std::cos(a) * std::cos(b)), float(std::sin(a) * std::cos(b)), float(std::sin(b))};
      const Ray in{s.center() - dir * float(5 * r), dir, 0.0f, kInfinity};
      float t = 0;
      REQUIRE(intersect_sphere(in, s.center(), s.radius(), kInfinity, t));
      Hit hit;
      hit.t = t;
      hit.primitive = 0;
      const HitPoint hp = hit_point(s, in, hit);
      const Vec3 n = geometric_normal(s, hp.p);
      float t2 = 0;
      // Reflected: out on the outside, heading away: no hit.
      const Vec3 refl = dir - n * (2 * dot(dir, n));
      CHECK_FALSE(intersect_sphere(Ray{offset_ray_origin(hp, n), refl, 0.0f, kInfinity}, s.center(), s.radius(),
                                   kInfinity, t2));
      // Refracted straight on from just inside: the far side, about 2r away, not a self-hit.
      REQUIRE(intersect_sphere(Ray{offset_ray_origin(hp, -n), dir, 0.0f, kInfinity}, s.center(), s.radius(),
                               kInfinity, t2));
      CHECK(t2 > 1.9 * r);
    }
  }
}

TEST_CASE("triangle: an origin in the triangle's plane does not hit it at a rounding-noise t") {
  // Before: t ~ 1e-7 was accepted, and an eye standing in a floor polygon's
  // plane saw speckle over the whole image.
  const Primitive floor = triangle({-10, -10, 0}, {10, -10, 0}, {0, 10, 0});
  int hits = 0;
  for (int i = 0; i < 400; ++i) {
    // Nearly horizontal directions: the test's z axis is x or y, so the
    // sheared z values are not 0 and their combination is rounding noise.
    const float a = 0.05f + 0.0157f * float(i);
    const Vec3 dir{std::cos(a), std::sin(a), 0.3f * std::sin(7 * a)};
    float t = 0;
    hits += hits_triangle(Ray{{0.3f, 0.2f, 0.0f}, dir, 0.0f, kInfinity}, floor, t);
    hits += hits_triangle(Ray{{-1.7f, -3.1f, 0.0f}, dir * 1e4f, 0.0f, kInfinity}, floor, t);
  }
  CHECK(hits == 0);
  // A real hit at a small distance still counts.
  float t = 0;
  CHECK(hits_triangle(Ray{{0.3f, 0.2f, 1e-3f}, {0.0f, 0.0f, -1.0f}, 0.0f, kInfinity}, floor, t));
  CHECK(t == doctest::Approx(1e-3));
}

TEST_CASE("cone: the same ray hits a cylinder and a cone alike at scales 1e-6 .. 1e6") {
  // Before: a tolerance compared the dimensionless quadratic coefficient
  // with a squared length; at 1e6 every ray took the "linear" branch.
  for (const float ra : {1.0f, 0.25f}) {
    const Vec3 base{0, 0, -2}, apex{0, 0, 2};
    const Ray unit{{5, 0.3f, 0.1f}, {-1, 0.05f, 0.02f}, 0.0f, kInfinity};
    float t1 = 0;
    REQUIRE(intersect_cone(unit, base, 1.0f, apex, ra, kInfinity, t1));
    for (double s : {1e-6, 1e-3, 1e3, 1e6}) {
      CAPTURE(s);
      const float fs = float(s);
      const Ray r{unit.origin * fs, unit.direction * 3.0f, 0.0f, kInfinity};  // direction of any length
      float t = 0;
      REQUIRE(intersect_cone(r, base * fs, fs, apex * fs, ra * fs, kInfinity, t));
      CHECK(double(t) * 3.0 == doctest::Approx(double(t1) * s).epsilon(1e-5));
    }
  }
  // A ray parallel to a cylinder's side misses; one parallel to a cone's
  // slant line meets it once.
  float t = 0;
  CHECK_FALSE(intersect_cone(Ray{{2, 0, -5}, {0, 0, 1}, 0.0f, kInfinity}, {0, 0, -2}, 1.0f, {0, 0, 2}, 1.0f,
                             kInfinity, t));
  CHECK(intersect_cone(Ray{{0.5f, 0, -3}, {-1, 0, 4}, 0.0f, kInfinity}, {0, 0, -2}, 1.0f, {0, 0, 2}, 0.0f,
                       kInfinity, t));
}

TEST_CASE("normals: a small sphere and cone far from the origin get the normal of the exact point, not of its rounding") {
  // At 1e4 a float's spacing is 1e-3, 2% of these radii: a normal taken
  // from the rounded hit point would tilt by up to about that much.
  const double far = 1e4, r = 0.05;
  const Vec3 c{float(far + 0.3), float(far - 0.2), float(far + 0.1)};
  Primitive sphere;
  sphere.kind = PrimitiveKind::kSphere;
  for (int k = 0; k < 3; ++k) sphere.data[k] = c[k];
  sphere.data[3] = float(r);
  // A cone along z (base radius r, apex radius r / 2) beside it.
  Primitive cone;
  cone.kind = PrimitiveKind::kCone;
  const Vec3 base{c.x + 1, c.y, c.z - 0.2f}, apex{c.x + 1, c.y, c.z + 0.2f};
  for (int k = 0; k < 3; ++k) {
    cone.data[k] = base[k];
    cone.data[4 + k] = apex[k];
  }
  cone.data[3] = float(r);
  cone.data[7] = float(r / 2);
  double worst_sphere = 0, worst_cone = 0, worst_rounded = 0;
  for (int i = 0; i < 200; ++i) {
    const double a = 0.1 + i * 0.031, b = -0.6 + i * 0.006;
    const Vec3 dir{float(std::cos(a) * std::cos(b)), float(std::sin(a) * std::cos(b)), float(std::sin(b))};
    for (const Primitive* p : {&sphere, &cone}) {
      const Vec3 target = p == &sphere ? c : Vec3{base.x, base.y, c.z};
      const Ray ray{target - dir * 3.0f, dir, 0.0f, kInfinity};
      float t = 0;
      const bool hit_it = p == &sphere ? intersect_sphere(ray, p->center(), p->radius(), kInfinity, t)
                                       : intersect_cone(ray, p->cone_base(), p->cone_base_radius(), p->cone_apex(),
                                                        p->cone_apex_radius(), kInfinity, t);
      if (!hit_it) continue;
      Hit hit;
      hit.t = t;
      hit.primitive = 0;
      const HitPoint hp = hit_point(*p, ray, hit);
      // The exact point in double, relative to the primitive (exact differences of floats).
      double q[3], n[3];
      for (int k = 0; k < 3; ++k) q[k] = (double(ray.origin[k]) - p->data[k]) + double(t) * ray.direction[k];
      if (p == &sphere) {
        for (int k = 0; k < 3; ++k) n[k] = q[k];
      } else {  // along z: the radial part, tilted by the slope (apex radius - base radius) / height
        const double h = double(p->data[6]) - p->data[2], rb = p->data[3], ra = p->data[7];
        const double slope = (ra - rb) / h, radius = rb + slope * q[2], len = std::hypot(q[0], q[1]);
        n[0] = q[0] / len * radius;
        n[1] = q[1] / len * radius;
        n[2] = -slope * radius;
      }
      const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      const Vec3 from_rounded = geometric_normal(*p, hp.p);
      double err = 0;
      for (int k = 0; k < 3; ++k) {
        err = std::max(err, std::fabs(double(hp.normal[k]) - n[k] / len));
        worst_rounded = std::max(worst_rounded, std::fabs(double(from_rounded[k]) - n[k] / len));
      }
      (p == &sphere ? worst_sphere : worst_cone) = std::max(p == &sphere ? worst_sphere : worst_cone, err);
    }
  }
  CHECK(worst_sphere < 1e-5);
  CHECK(worst_cone < 1e-5);
  CHECK(worst_rounded > 1e-3);  // what a normal from the rounded point errs by here
}

TEST_CASE("normals: triangles with edges of 1e10 to 1e30 and of 1e-20 get a unit normal") {
  // Before: the squared length overflowed float and the normal came out 0.
  for (float s : {1e-20f, 1e10f, 1e15f, 1e30f}) {
    CAPTURE(s);
    const Primitive tri = triangle({0, 0, 0}, {s, 0, 0}, {0, s, 0});
    const Vec3 n = geometric_normal(tri, {0, 0, 0});
    CHECK(n.z == doctest::Approx(1.0f));
    CHECK(length(n) == doctest::Approx(1.0f));
  }
}

TEST_CASE("view: an 'up' of any length is accepted, one parallel to the view direction is not") {
  const std::string text = "v\nfrom 0 0 5\nat 0 0 0\nup 0 1e20 0\nangle 45\nhither 0\nresolution 8 8\ns 0 0 0 1\n";
  const Scene s = parse_nff(text);  // before: "'up' is parallel to the viewing direction (or too long)"
  const Camera cam(s.view, 8, 8);
  const Scene small = parse_nff("v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 0\nresolution 8 8\n");
  const Camera ref(small.view, 8, 8);
  CHECK(cam.ray_through(1.5f, 2.5f).direction == ref.ray_through(1.5f, 2.5f).direction);
  CHECK_THROWS_AS(parse_nff("v\nfrom 0 0 5\nat 0 0 0\nup 0 0 1e30\nangle 45\nhither 0\nresolution 8 8\n"),
                  ParseError);
  CHECK(up_is_usable({0, 0, -1}, {0, 1e-30f, 0}));
  CHECK_FALSE(up_is_usable({0, 0, -1}, {0, 0, 0}));
}

TEST_CASE("camera: eye rays start at the view's hither distance") {
  View v;
  v.from = {0, 0, 5};
  v.at = {0, 0, 0};
  v.hither = 0.25f;
  CHECK(Camera(v, 4, 4).ray_through(2, 2).tmin == 0.25f);
  v.hither = 0;
  CHECK(Camera(v, 4, 4).ray_through(2, 2).tmin == 0.0f);
}

TEST_CASE("transform_scene: scales and moves geometry, lights and view, and refuses what float cannot hold") {
  Scene s = parse_nff("v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 1\nresolution 8 8\nl 1 2 3\n"
                      "f 1 0 0 1 0 0 0 0\ns 1 1 1 0.5\nc 0 0 0 1 0 0 2 0.5\np 3\n0 0 0\n1 0 0\n0 1 0\n");
  SceneTransform t;
  t.scale = 1e3;
  t.translate = {10, 0, -5};
  transform_scene(s, t);
  CHECK(s.view.from == Vec3{10, 0, 4995});
  CHECK(s.view.up == Vec3{0, 1, 0});
  CHECK(s.view.hither == 1000.0f);
  CHECK(s.lights[0].position == Vec3{1010, 2000, 2995});
  CHECK(s.spheres[0].center == Vec3{1010, 1000, 995});
  CHECK(s.spheres[0].radius == 500.0f);
  CHECK(s.cones[0].apex == Vec3{10, 0, 1995});
  CHECK(s.cones[0].base_radius == 1000.0f);
  CHECK(s.vertices[1] == Vec3{1010, 0, -5});
  SceneTransform bad;
  bad.scale = 0;
  CHECK_THROWS_AS(transform_scene(s, bad), std::invalid_argument);
  bad.scale = 1e36;
  CHECK_THROWS_AS(transform_scene(s, bad), std::invalid_argument);
}

TEST_CASE("eye_at_origin: the rendering space puts the eye, or the bounds' centre, at the origin") {
  const char* nff = "v\nfrom 1000.5 -2000 3000.25\nat 1000 -2000 3000\nup 0 1 0\nangle 45\nhither 1\nresolution 8 8\n"
                    "l 1001 -1998 3002\nf 1 0 0 1 0 0 0 0\ns 1001 -1999 3001 0.5\np 3\n1000 -2000 3000\n1001 -2000 3000\n"
                    "1000 -1999 3000\n";
  Scene s = parse_nff(nff);
  const SceneTransform t = eye_at_origin(s);
  CHECK(t.scale == 1.0);
  CHECK(t.translate == std::array<double, 3>{-1000.5, 2000, -3000.25});
  transform_scene(s, t);
  CHECK(s.view.from == Vec3{0, 0, 0});
  CHECK(s.view.at == Vec3{-0.5f, 0, -0.25f});  // exact differences: the view's direction is kept
  CHECK(s.lights[0].position == Vec3{0.5f, 2, 1.75f});
  CHECK(s.spheres[0].center == Vec3{0.5f, 1, 0.75f});
  CHECK(s.vertices[2] == Vec3{-0.5f, 1, -0.25f});
  // No view: the centre of the bounds.
  Scene nv = parse_nff("f 1 0 0 1 0 0 0 0\np 3\n100 200 300\n102 200 300\n100 204 306\n");
  nv.has_view = false;
  const SceneTransform c = eye_at_origin(nv);
  CHECK(c.translate == std::array<double, 3>{-101, -202, -303});
  // A difference beyond float's range: left where it is.
  Scene wide = parse_nff(nff);
  wide.vertices[0] = Vec3{-3e38f, 0, 0};
  wide.view.from = Vec3{3e38f, 0, 0};
  CHECK(eye_at_origin(wide).is_identity());
}

TEST_CASE("eye_at_origin_after: a translation cancels exactly, a scale is rounded once, and errors are kept") {
  // Thirds: a float cannot hold them at 1e4, so rounding the moved scene
  // first and then moving the eye to the origin loses them.
  const char* nff = "v\nfrom 0.333333343 1.66666663 2.33333325\nat 0 0 0\nup 0 0 1\nangle 45\nhither 0.1\n"
                    "resolution 8 8\nl 1 2 3\nf 1 0 0 1 0 0 0 0\ns 0.666666687 0.111111112 0.444444448 0.0370370373\n"
                    "p 3\n0.142857149 0 0\n1 0.428571433 0\n0 0 0.285714298\n";
  const Scene original = parse_nff(nff);
  Scene here = original;
  transform_scene(here, eye_at_origin(here));
  SceneTransform move;
  move.translate = {1e4, -1e4, 1e4};
  Scene moved = original;
  transform_scene(moved, eye_at_origin_after(moved, move));
  CHECK(moved.vertices == here.vertices);
  CHECK(moved.spheres[0].center == here.spheres[0].center);
  CHECK(moved.spheres[0].radius == here.spheres[0].radius);
  CHECK(moved.lights[0].position == here.lights[0].position);
  CHECK(moved.view.at == here.view.at);
  // Two steps (round at 1e4, then move the eye) lose the thirds.
  Scene two_steps = original;
  transform_scene(two_steps, move);
  transform_scene(two_steps, eye_at_origin(two_steps));
  CHECK(two_steps.vertices != here.vertices);
  // A power-of-two scale: exactly the rebased scene's coordinates, doubled.
  SceneTransform twice;
  twice.scale = 2;
  twice.translate = {1e4, 0, -1e4};
  Scene scaled = original;
  transform_scene(scaled, eye_at_origin_after(scaled, twice));
  for (std::size_t i = 0; i < here.vertices.size(); ++i) CHECK(scaled.vertices[i] == here.vertices[i] * 2.0f);
  CHECK(scaled.spheres[0].radius == 2.0f * here.spheres[0].radius);
  // An eye already at the origin: the translation still cancels.
  Scene at_origin = original;
  at_origin.view.from = Vec3{0, 0, 0};
  Scene at_origin_moved = at_origin;
  transform_scene(at_origin_moved, eye_at_origin_after(at_origin_moved, move));
  CHECK(at_origin_moved.vertices == at_origin.vertices);
  // What transform_scene would refuse is refused, and nothing is changed.
  SceneTransform far;
  far.translate = {1e39, 0, 0};
  Scene kept = original;
  CHECK_THROWS_AS(eye_at_origin_after(kept, far), std::invalid_argument);
  CHECK_THROWS_AS(check_transform(kept, far), std::invalid_argument);
  CHECK(kept.vertices == original.vertices);
  SceneTransform bad;
  bad.scale = -1;
  CHECK_THROWS_AS(check_transform(kept, bad), std::invalid_argument);
}
