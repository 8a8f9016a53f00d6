// Tests of the single-primitive ray tests (intersect.h) and the ray/box
// helpers of math.h: analytic distances for spheres, open cylinders and
// cones; the open interval (tmin, tmax); watertightness of the triangle test
// on shared edges and vertices; rejection of invalid rays.
#include <doctest/doctest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "core/database.h"
#include "core/intersect.h"
#include "core/math.h"

#include "test_random.h"

namespace {

using namespace raynode::core;
using raynode::testing::Rng;
using raynode::testing::random_in_cube;
using raynode::testing::random_unit;
using raynode::testing::uniform;

bool sphere(const Ray& r, const Vec3& c, float radius, float& t) { return intersect_sphere(r, c, radius, r.tmax, t); }

bool cone(const Ray& r, const Vec3& base, float rb, const Vec3& apex, float ra, float& t) {
  return intersect_cone(r, base, rb, apex, ra, r.tmax, t);
}

bool triangle(const Ray& r, const Vec3& v0, const Vec3& v1, const Vec3& v2, TriangleHit& h) {
  return intersect_triangle(r, WatertightRay(r.direction), v0, v1, v2, r.tmax, h);
}
bool triangle(const Ray& r, const Vec3& v0, const Vec3& v1, const Vec3& v2) {
  TriangleHit h;
  return triangle(r, v0, v1, v2, h);
}

// A rotation (about a tilted axis) and a translation, for invariance tests.
struct Motion {
  float m[3][3];
  Vec3 offset;
  Motion(const Vec3& axis_in, float angle, const Vec3& off) : offset(off) {
    const Vec3 a = normalize(axis_in);
    const float c = std::cos(angle), s = std::sin(angle), t = 1 - c;
    const float r[3][3] = {{t * a.x * a.x + c, t * a.x * a.y - s * a.z, t * a.x * a.z + s * a.y},
                           {t * a.x * a.y + s * a.z, t * a.y * a.y + c, t * a.y * a.z - s * a.x},
                           {t * a.x * a.z - s * a.y, t * a.y * a.z + s * a.x, t * a.z * a.z + c}};
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) m[i][j] = r[i][j];
  }
  Vec3 dir(const Vec3& v) const {
    return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z, m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
            m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
  }
  Vec3 point(const Vec3& p) const { return dir(p) + offset; }
  Ray ray(const Ray& r) const { return {point(r.origin), dir(r.direction), r.tmin, r.tmax}; }
};

}  // namespace

// ---------------------------------------------------------------------------
// Spheres

TEST_CASE("intersect: sphere hit from outside at the analytic distance, whatever the direction's length") {
  const Vec3 c{1, 2, 3};
  float t = 0;
  REQUIRE(sphere({{1, 2, -2}, {0, 0, 1}, 0, kInfinity}, c, 1.0f, t));
  CHECK(t == 4.0f);
  // t is in units of |direction|.
  REQUIRE(sphere({{1, 2, -2}, {0, 0, 2}, 0, kInfinity}, c, 1.0f, t));
  CHECK(t == 2.0f);
  REQUIRE(sphere({{1, 2, -2}, {0, 0, 0.25f}, 0, kInfinity}, c, 1.0f, t));
  CHECK(t == 16.0f);
  // Off-centre: the chord at distance 0.6 from the centre enters 0.8 early.
  REQUIRE(sphere({{1.6f, 2, -2}, {0, 0, 1}, 0, kInfinity}, c, 1.0f, t));
  CHECK(t == doctest::Approx(4.2f).epsilon(1e-6));
  // Oblique, random: the hit point lies on the sphere and is the nearer root.
  Rng rng(1);
  for (int i = 0; i < 2000; ++i) {
    const Vec3 o = c + random_unit(rng) * uniform(rng, 1.5f, 10.0f);
    const Vec3 target = c + random_unit(rng) * 0.9f;
    const Ray r{o, (target - o) * uniform(rng, 0.1f, 10.0f), 0, kInfinity};
    REQUIRE(sphere(r, c, 1.0f, t));
    CHECK(length(r.at(t) - c) == doctest::Approx(1.0f).epsilon(1e-5));
    CHECK(dot(r.at(t) - c, r.direction) < 0.0f);  // entering: the near side
  }
}

TEST_CASE("intersect: sphere hit from inside gives the exit distance") {
  float t = 0;
  REQUIRE(sphere({{0, 0, 0}, {1, 0, 0}, 0, kInfinity}, {0, 0, 0}, 2.0f, t));
  CHECK(t == 2.0f);
  // From an off-centre inside point: exit at x = sqrt(4 - 1) - 0.5.
  REQUIRE(sphere({{0.5f, 1, 0}, {1, 0, 0}, 0, kInfinity}, {0, 0, 0}, 2.0f, t));
  CHECK(t == doctest::Approx(std::sqrt(3.0) - 0.5).epsilon(1e-6));
  REQUIRE(sphere({{0.5f, 1, 0}, {-1, 0, 0}, 0, kInfinity}, {0, 0, 0}, 2.0f, t));
  CHECK(t == doctest::Approx(std::sqrt(3.0) + 0.5).epsilon(1e-6));
}

TEST_CASE("intersect: a ray just inside a sphere's silhouette hits at the analytic distance, just outside misses") {
  for (float gap : {1e-2f, 1e-4f, 1e-6f}) {
    CAPTURE(gap);
    const float y_in = 1.0f - gap, y_out = 1.0f + gap;
    float t = 0;
    REQUIRE(sphere({{-5, y_in, 0}, {1, 0, 0}, 0, kInfinity}, {0, 0, 0}, 1.0f, t));
    const double y = y_in;  // the float actually used
    CHECK(t == doctest::Approx(5.0 - std::sqrt(1.0 - y * y)).epsilon(1e-7));
    CHECK_FALSE(sphere({{-5, y_out, 0}, {1, 0, 0}, 0, kInfinity}, {0, 0, 0}, 1.0f, t));
  }
}

TEST_CASE("intersect: a small sphere far away is hit at the right distance (stable quadratic)") {
  float t = 0;
  REQUIRE(sphere({{0, 0, 0}, {0, 0, 1}, 0, kInfinity}, {0, 0, 1e4f}, 0.01f, t));
  CHECK(t == doctest::Approx(1e4 - 0.01).epsilon(1e-7));
  REQUIRE(sphere({{0, 0.005f, 0}, {0, 0, 1}, 0, kInfinity}, {0, 0, 1e4f}, 0.01f, t));
  CHECK(t == doctest::Approx(1e4 - std::sqrt(1e-4 - 2.5e-5)).epsilon(1e-7));
  CHECK_FALSE(sphere({{0, 0.0101f, 0}, {0, 0, 1}, 0, kInfinity}, {0, 0, 1e4f}, 0.01f, t));
}

// intersect_sphere's quadratic without its early outs (a sphere behind the
// origin, a nearer root past tmax): what they must never change.
bool sphere_full_quadratic(const Ray& ray, const Vec3& center, float radius, float tmax, float& t_out) {
  const double fx = double(ray.origin.x) - center.x, fy = double(ray.origin.y) - center.y,
               fz = double(ray.origin.z) - center.z;
  const double dx = ray.direction.x, dy = ray.direction.y, dz = ray.direction.z;
  const double a = dx * dx + dy * dy + dz * dz;
  const double b = -(fx * dx + fy * dy + fz * dz);
  const double s = b / a;
  const double lx = fx + s * dx, ly = fy + s * dy, lz = fz + s * dz;
  const double r = double(radius);
  const double disc = a * (r * r - (lx * lx + ly * ly + lz * lz));
  if (disc < 0.0) return false;
  const double c = fx * fx + fy * fy + fz * fz - r * r;
  const double q = b + std::copysign(std::sqrt(disc), b);
  double t0 = (q != 0.0) ? c / q : 0.0, t1 = q / a;
  if (t0 > t1) std::swap(t0, t1);
  if (q == 0.0) t0 = t1;
  for (const double tt : {t0, t1}) {
    if (tt > ray.tmin && tt < tmax) {
      t_out = static_cast<float>(tt);
      return t_out > ray.tmin && t_out < tmax;
    }
  }
  return false;
}

TEST_CASE("intersect: the sphere test's early outs answer as its full quadratic, to the bit") {
  // Spheres 1e-6 to 1e3 across, 1e-3 to 1e6 away, ahead of and behind the
  // origin, rays from outside and inside, grazing ones, and tmax before,
  // at and past the roots (also a hair past the nearer root).
  Rng rng(71);
  std::size_t hits = 0, misses = 0, differ = 0;
  std::string first;
  for (int i = 0; i < 200000; ++i) {
    const float radius = std::pow(10.0f, uniform(rng, -6, 3));
    const float distance = radius * std::pow(10.0f, uniform(rng, -0.5f, 6));  // below 1: inside
    const Vec3 center = random_in_cube(rng, 10 * distance);
    const Vec3 dir = random_unit(rng);
    Vec3 side = cross(dir, std::fabs(dir.x) < 0.9f ? Vec3{1, 0, 0} : Vec3{0, 1, 0});
    side = side * (1.0f / std::sqrt(dot(side, side)));
    const double offset = (i % 3 == 0) ? 1.0 + (i % 2 ? 1 : -1) * std::pow(10.0, uniform(rng, -15, -3))
                                       : uniform(rng, 0, 1.2f);
    const Vec3 aim = center + side * float(radius * offset);
    const float behind = (i % 4 == 1) ? -1.0f : 1.0f;  // every fourth ray starts past the sphere
    const Vec3 origin = aim - dir * (behind * distance);
    const Vec3 d = dir * std::pow(10.0f, uniform(rng, -3, 3));
    const float scale = std::sqrt(dot(d, d));
    const float tmin = (i % 7 == 3) ? -distance / scale : 0.0f;
    float tmax = kInfinity;
    if (i % 5 == 1) tmax = uniform(rng, 0, 2) * distance / scale;
    float t_near = 0;
    if (i % 5 >= 2 && sphere_full_quadratic({origin, d, tmin, kInfinity}, center, radius, kInfinity, t_near)) {
      // tmax within a few float steps of the nearer root, either side.
      const std::uint32_t bits = std::bit_cast<std::uint32_t>(t_near);
      tmax = t_near > 0 ? std::bit_cast<float>(bits + std::uint32_t(i % 7) - 3u) : t_near;
    }
    const Ray r{origin, d, tmin, tmax};
    float t_fast = 0, t_full = 0;
    const bool fast = intersect_sphere(r, center, radius, r.tmax, t_fast);
    const bool full = sphere_full_quadratic(r, center, radius, r.tmax, t_full);
    (full ? hits : misses) += 1;
    if (fast != full || (fast && std::bit_cast<std::uint32_t>(t_fast) != std::bit_cast<std::uint32_t>(t_full)))
      if (!differ++) first = std::to_string(i);
  }
  INFO("first differing ray: " << first);
  CHECK(differ == 0);
  CHECK(hits > 20000);
  CHECK(misses > 20000);
}

TEST_CASE("intersect: a sphere behind the ray origin is missed") {
  float t = 0;
  CHECK_FALSE(sphere({{0, 0, 5}, {0, 0, 1}, 0, kInfinity}, {0, 0, 0}, 1.0f, t));
  CHECK_FALSE(sphere({{0, 0, 1.0001f}, {0, 0, 1}, 0, kInfinity}, {0, 0, 0}, 1.0f, t));
  // Pointing away from a sphere beside the ray line.
  CHECK_FALSE(sphere({{3, 0, 0}, {1, 1, 0}, 0, kInfinity}, {0, 0, 0}, 1.0f, t));
}

TEST_CASE("intersect: sphere hits are reported only in the open interval (tmin, tmax)") {
  const Vec3 c{0, 0, 0};
  const Vec3 o{0, 0, -5}, d{0, 0, 1};  // roots t = 4 and t = 6, exact
  float t = 0;
  CHECK_FALSE(sphere({o, d, 0, 4.0f}, c, 1.0f, t));  // tmax excluded
  REQUIRE(sphere({o, d, 0, 4.0001f}, c, 1.0f, t));
  CHECK(t == 4.0f);
  REQUIRE(sphere({o, d, 4.0f, kInfinity}, c, 1.0f, t));  // tmin excluded: the far root
  CHECK(t == 6.0f);
  CHECK_FALSE(sphere({o, d, 4.0f, 6.0f}, c, 1.0f, t));  // both ends excluded
  REQUIRE(sphere({o, d, 3.9999f, 6.0f}, c, 1.0f, t));
  CHECK(t == 4.0f);
  REQUIRE(sphere({o, d, 5.9f, 6.1f}, c, 1.0f, t));
  CHECK(t == 6.0f);
  CHECK_FALSE(sphere({o, d, 6.0f, kInfinity}, c, 1.0f, t));
  // The tmax argument, not ray.tmax, bounds the hit (the traversal passes its best t).
  CHECK_FALSE(intersect_sphere({o, d, 0, kInfinity}, c, 1.0f, 3.5f, t));
  CHECK(intersect_sphere({o, d, 0, 3.5f}, c, 1.0f, 4.5f, t));
}

TEST_CASE("intersect: a negative sphere radius acts as its magnitude") {
  float t1 = 0, t2 = 0;
  REQUIRE(sphere({{0, 0.3f, -5}, {0, 0, 1}, 0, kInfinity}, {0, 0, 0}, -1.5f, t1));
  REQUIRE(sphere({{0, 0.3f, -5}, {0, 0, 1}, 0, kInfinity}, {0, 0, 0}, 1.5f, t2));
  CHECK(t1 == t2);
}

// ---------------------------------------------------------------------------
// Cylinders and cones (open: no caps)

TEST_CASE("intersect: a cylinder is hit between its end planes only, at the analytic distance") {
  const Vec3 base{0, 0, 0}, apex{0, 0, 2};
  float t = 0;
  REQUIRE(cone({{-5, 0, 1}, {1, 0, 0}, 0, kInfinity}, base, 1, apex, 1, t));
  CHECK(t == doctest::Approx(4.0).epsilon(1e-7));
  // Off-axis chord: x = -sqrt(1 - 0.36) = -0.8.
  REQUIRE(cone({{-5, 0.6f, 1}, {1, 0, 0}, 0, kInfinity}, base, 1, apex, 1, t));
  CHECK(t == doctest::Approx(4.2).epsilon(1e-6));
  // From inside: the far wall.
  REQUIRE(cone({{0, 0, 1}, {1, 0, 0}, 0, kInfinity}, base, 1, apex, 1, t));
  CHECK(t == doctest::Approx(1.0).epsilon(1e-7));
  // Near the end planes: inside hits, outside misses.
  CHECK(cone({{-5, 0, 1.999f}, {1, 0, 0}, 0, kInfinity}, base, 1, apex, 1, t));
  CHECK(cone({{-5, 0, 0.001f}, {1, 0, 0}, 0, kInfinity}, base, 1, apex, 1, t));
  CHECK_FALSE(cone({{-5, 0, 2.001f}, {1, 0, 0}, 0, kInfinity}, base, 1, apex, 1, t));
  CHECK_FALSE(cone({{-5, 0, -0.001f}, {1, 0, 0}, 0, kInfinity}, base, 1, apex, 1, t));
  CHECK_FALSE(cone({{-5, 0, 3}, {1, 0, 0}, 0, kInfinity}, base, 1, apex, 1, t));
  // An oblique ray whose near root lies above the top plane (x = -1 at
  // z = 2.5) passes in through the open end and hits the far wall from
  // inside at (1, 0, 1.5), t = 4.
  REQUIRE(cone({{-3, 0, 3.5f}, {1, 0, -0.5f}, 0, kInfinity}, base, 1, apex, 1, t));
  CHECK(t == doctest::Approx(4.0).epsilon(1e-6));
}

TEST_CASE("intersect: an open cylinder lets rays in through its ends: along the axis it is missed") {
  const Vec3 base{0, 0, 0}, apex{0, 0, 2};
  float t = 0;
  CHECK_FALSE(cone({{0, 0, -5}, {0, 0, 1}, 0, kInfinity}, base, 1, apex, 1, t));    // along the axis, from outside
  CHECK_FALSE(cone({{0, 0, 1}, {0, 0, 1}, 0, kInfinity}, base, 1, apex, 1, t));     // along the axis, from inside
  CHECK_FALSE(cone({{0.5f, 0, -5}, {0, 0, 1}, 0, kInfinity}, base, 1, apex, 1, t)); // parallel to the axis, inside
  // Entering through the open top at (0.5, 0, 2) and meeting the inside of
  // the wall at (1, 0, 1): t = 2.
  REQUIRE(cone({{0, 0, 3}, {0.5f, 0, -1}, 0, kInfinity}, base, 1, apex, 1, t));
  CHECK(t == doctest::Approx(2.0).epsilon(1e-6));
  // Too steep: through both open ends without touching the wall.
  CHECK_FALSE(cone({{0, 0, 3}, {0.1f, 0, -1}, 0, kInfinity}, base, 1, apex, 1, t));
}

TEST_CASE("intersect: a cone is hit at the analytic distance, its other nappe and the parts beyond its ends are missed") {
  // Base radius 1 at z = 0, apex radius 0 at z = 1: radius 1 - z.
  const Vec3 base{0, 0, 0}, apex{0, 0, 1};
  float t = 0;
  REQUIRE(cone({{-5, 0, 0.5f}, {1, 0, 0}, 0, kInfinity}, base, 1, apex, 0, t));
  CHECK(t == doctest::Approx(4.5).epsilon(1e-7));
  REQUIRE(cone({{0, -5, 0.25f}, {0, 1, 0}, 0, kInfinity}, base, 1, apex, 0, t));
  CHECK(t == doctest::Approx(4.25).epsilon(1e-7));
  // The mathematical double cone continues above the apex (radius z - 1) and
  // below the base (radius 1 - z): neither is part of the primitive.
  CHECK_FALSE(cone({{-5, 0, 1.5f}, {1, 0, 0}, 0, kInfinity}, base, 1, apex, 0, t));
  CHECK_FALSE(cone({{-5, 0, -0.5f}, {1, 0, 0}, 0, kInfinity}, base, 1, apex, 0, t));
  // A truncated cone: radius 2 at z = 0 to 1 at z = 2, so 1.5 at z = 1.
  REQUIRE(cone({{0, -5, 1}, {0, 1, 0}, 0, kInfinity}, base, 2, {0, 0, 2}, 1, t));
  CHECK(t == doctest::Approx(3.5).epsilon(1e-7));
  REQUIRE(cone({{0, 0, 1}, {0, 1, 0}, 0, kInfinity}, base, 2, {0, 0, 2}, 1, t));  // from inside
  CHECK(t == doctest::Approx(1.5).epsilon(1e-7));
  // Swapping base and apex describes the same surface.
  float t2 = 0;
  REQUIRE(cone({{0, -5, 1}, {0, 1, 0}, 0, kInfinity}, {0, 0, 2}, 1, base, 2, t2));
  CHECK(t2 == doctest::Approx(3.5).epsilon(1e-7));
  // Negative radii act as their magnitudes.
  REQUIRE(cone({{0, -5, 1}, {0, 1, 0}, 0, kInfinity}, base, -2, {0, 0, 2}, -1, t2));
  CHECK(t2 == doctest::Approx(3.5).epsilon(1e-7));
}

TEST_CASE("intersect: cone and cylinder distances do not change when ray and axis are rotated and moved together") {
  const Motion motions[] = {Motion({1, 2, 3}, 0.7f, {10, -20, 5}), Motion({0, 0, 1}, 1.5707964f, {0, 0, 0}),
                            Motion({-1, 0.2f, 0.1f}, 2.9f, {-300, 200, 1000})};
  const struct {
    Ray ray;
    Vec3 base;
    float rb;
    Vec3 apex;
    float ra;
    double t;  // analytic, or < 0 for a miss
  } cases[] = {
      {{{-5, 0, 0.5f}, {1, 0, 0}, 0, kInfinity}, {0, 0, 0}, 1, {0, 0, 1}, 0, 4.5},
      {{{0, -5, 1}, {0, 1, 0}, 0, kInfinity}, {0, 0, 0}, 2, {0, 0, 2}, 1, 3.5},
      {{{-5, 0, 1}, {1, 0, 0}, 0, kInfinity}, {0, 0, 0}, 1, {0, 0, 2}, 1, 4.0},
      {{{0, 0, 3}, {0.5f, 0, -1}, 0, kInfinity}, {0, 0, 0}, 1, {0, 0, 2}, 1, 2.0},
      {{{0, 0, -5}, {0, 0, 1}, 0, kInfinity}, {0, 0, 0}, 1, {0, 0, 2}, 1, -1},
      {{{-5, 0, 2.5f}, {1, 0, 0}, 0, kInfinity}, {0, 0, 0}, 1, {0, 0, 2}, 1, -1},
  };
  for (const Motion& m : motions)
    for (const auto& c : cases) {
      CAPTURE(c.t);
      float t = 0;
      const bool hit = cone(m.ray(c.ray), m.point(c.base), c.rb, m.point(c.apex), c.ra, t);
      CHECK(hit == (c.t > 0));
      if (hit && c.t > 0) CHECK(t == doctest::Approx(c.t).epsilon(2e-5));
    }
}

TEST_CASE("intersect: cone hits are reported only in the open interval (tmin, tmax)") {
  const Vec3 base{0, 0, 0}, apex{0, 0, 2};
  const Vec3 o{-5, 0, 1}, d{1, 0, 0};  // walls at t = 4 and t = 6
  float t = 0;
  CHECK_FALSE(cone({o, d, 0, 3.99f}, base, 1, apex, 1, t));
  REQUIRE(cone({o, d, 0, 4.01f}, base, 1, apex, 1, t));
  CHECK(t == doctest::Approx(4.0));
  REQUIRE(cone({o, d, 4.01f, kInfinity}, base, 1, apex, 1, t));
  CHECK(t == doctest::Approx(6.0));
  CHECK_FALSE(cone({o, d, 4.01f, 5.99f}, base, 1, apex, 1, t));
  CHECK_FALSE(cone({o, d, 6.01f, kInfinity}, base, 1, apex, 1, t));
}

// ---------------------------------------------------------------------------
// Triangles

TEST_CASE("intersect: a triangle is hit from both sides with t and barycentrics that reproduce the hit point") {
  const Vec3 v0{0, 0, 0}, v1{1, 0, 0}, v2{0, 1, 0};
  TriangleHit h{};
  REQUIRE(triangle({{0.25f, 0.5f, 1}, {0, 0, -1}, 0, kInfinity}, v0, v1, v2, h));
  CHECK(h.t == 1.0f);
  CHECK(h.u == doctest::Approx(0.25f));  // weight of v1
  CHECK(h.v == doctest::Approx(0.5f));   // weight of v2
  REQUIRE(triangle({{0.25f, 0.5f, -2}, {0, 0, 1}, 0, kInfinity}, v0, v1, v2, h));  // from behind
  CHECK(h.t == 2.0f);
  CHECK_FALSE(triangle({{0.75f, 0.5f, 1}, {0, 0, -1}, 0, kInfinity}, v0, v1, v2, h));  // beside it
  CHECK_FALSE(triangle({{0.25f, 0.5f, -1}, {0, 0, -1}, 0, kInfinity}, v0, v1, v2, h));  // behind the origin
  // Random triangles and random interior targets.
  Rng rng(2);
  for (int i = 0; i < 5000; ++i) {
    const Vec3 a = random_in_cube(rng, 3), b = random_in_cube(rng, 3), c = random_in_cube(rng, 3);
    if (length(cross(b - a, c - a)) < 0.5f) continue;
    float wu = uniform(rng, 0.02f, 0.96f), wv = uniform(rng, 0.02f, 0.96f);
    if (wu + wv > 0.98f) {
      wu = 0.98f - wu;
      wv = 0.98f - wv;
      if (wu < 0.01f || wv < 0.01f) continue;
    }
    const Vec3 target = a + (b - a) * wu + (c - a) * wv;
    const Vec3 o = target + random_unit(rng) * uniform(rng, 0.5f, 20.0f);
    const Ray r{o, (target - o) * uniform(rng, 0.1f, 3.0f), 0, kInfinity};
    if (std::fabs(dot(normalize(r.direction), normalize(cross(b - a, c - a)))) < 0.05f) continue;  // grazing
    REQUIRE(triangle(r, a, b, c, h));
    CHECK(h.u == doctest::Approx(wu).epsilon(1e-3).scale(1));
    CHECK(h.v == doctest::Approx(wv).epsilon(1e-3).scale(1));
    const Vec3 p = a * (1 - h.u - h.v) + b * h.u + c * h.v;
    CHECK(length(r.at(h.t) - p) < 1e-4f * (1.0f + length(o)));
  }
}

TEST_CASE("intersect: triangle hits are reported only in the open interval (tmin, tmax)") {
  const Vec3 v0{0, 0, 0}, v1{1, 0, 0}, v2{0, 1, 0};
  const Vec3 o{0.2f, 0.2f, 2}, d{0, 0, -1};  // t = 2
  TriangleHit h{};
  CHECK_FALSE(triangle({o, d, 0, 2.0f}, v0, v1, v2, h));
  CHECK(triangle({o, d, 0, 2.001f}, v0, v1, v2, h));
  CHECK_FALSE(triangle({o, d, 2.0f, kInfinity}, v0, v1, v2, h));
  CHECK(triangle({o, d, 1.999f, kInfinity}, v0, v1, v2, h));
  // The separate tmax argument bounds the hit.
  CHECK_FALSE(intersect_triangle({o, d, 0, kInfinity}, WatertightRay(d), v0, v1, v2, 1.5f, h));
}

TEST_CASE("intersect: rays through the shared edge of two triangles hit one or both, never neither") {
  Rng rng(3);
  std::size_t rays = 0, neither = 0, one = 0, both = 0;
  // Far from the origin and small or large. The target point on the edge is
  // rounded to float (by up to ~2e-4 of the edge length for these
  // placements), so the ray passes beside the edge by that much: targets
  // keep 10% away from the end points, and both triangles must be seen at
  // more than 0.05 rad from edge-on, so that each covers far more than the
  // rounding on its side of the edge.
  const struct {
    float offset, scale;
  } placements[] = {{0, 1}, {0, 1e-3f}, {0, 50}, {1e3f, 1}, {1e3f, 50}, {-7.5e4f, 50}};
  for (const auto& [offset, scale] : placements) {
    for (int pair = 0; pair < 40; ++pair) {
      // Triangles (a, b, c) and (b, a, d): consistently wound, sharing a-b.
      const Vec3 shift{offset, -offset, 0.5f * offset};
      const Vec3 a = random_in_cube(rng, scale) + shift, b = random_in_cube(rng, scale) + shift;
      const Vec3 mid = (a + b) * 0.5f;
      const Vec3 side = normalize(cross(b - a, random_unit(rng)));
      const Vec3 c = mid + side * (scale * uniform(rng, 0.3f, 1.0f)) + random_unit(rng) * (0.3f * scale);
      const Vec3 d = mid - side * (scale * uniform(rng, 0.3f, 1.0f)) + random_unit(rng) * (0.3f * scale);
      if (length(b - a) < 0.2f * scale) continue;
      for (int i = 0; i < 500; ++i) {
        const Vec3 target = a + (b - a) * uniform(rng, 0.1f, 0.9f);
        const Vec3 o = target + random_unit(rng) * (scale * uniform(rng, 0.5f, 10.0f));
        // c and d must lie on opposite sides of the plane through o and
        // the edge (else the edge is a silhouette and a ray beside it
        // rightly misses both), each at a clear angle from it.
        const Vec3 n = normalize(cross(a - o, b - o));
        const float sc = dot(c - o, n) / length(c - o), sd = dot(d - o, n) / length(d - o);
        if (!(sc * sd < 0.0f) || std::fabs(sc) < 0.05f || std::fabs(sd) < 0.05f) continue;
        const Ray r{o, target - o, 0, kInfinity};
        const bool h1 = triangle(r, a, b, c), h2 = triangle(r, b, a, d);
        ++rays;
        neither += !h1 && !h2;
        one += h1 != h2;
        both += h1 && h2;
      }
    }
  }
  CAPTURE(one);
  CAPTURE(both);
  CHECK(rays > 50000);
  CHECK(neither == 0);
  CHECK(one > rays / 2);
}

TEST_CASE("intersect: rays exactly through a shared edge or vertex (integer coordinates) never slip between triangles") {
  // All coordinates are integers (scaled by powers of two), so the ray
  // passes exactly through the point on the edge, or exactly through the
  // vertex, and the float inputs carry no rounding at all.
  Rng rng(6);
  auto irand = [&](int lo, int hi) { return float(std::uniform_int_distribution<int>(lo, hi)(rng)); };
  auto ivec = [&](int lo, int hi) { return Vec3{irand(lo, hi), irand(lo, hi), irand(lo, hi)}; };
  std::size_t edge_rays = 0, vertex_rays = 0, missed = 0;
  for (const float offset : {0.0f, 4096.0f, -65536.0f})
    for (const float unit : {1.0f, 0.0078125f, 64.0f}) {
      if (std::fabs(offset) > 0 && unit < 1) continue;  // keep everything exact
      const Vec3 shift{offset, 0.5f * offset, -offset};
      for (int n = 0; n < 3000; ++n) {
        const Vec3 target = ivec(-50, 50);
        Vec3 e = ivec(-5, 5);
        if (dot(e, e) == 0.0f) continue;
        const Vec3 a = target - e * irand(1, 5), b = target + e * irand(1, 5);
        const Vec3 c = ivec(-60, 60), d = ivec(-60, 60), o = target + ivec(-60, 60);
        const Vec3 nrm = cross(a - o, b - o);
        const float sc = dot(c - o, nrm), sd = dot(d - o, nrm);
        if (!(sc * sd < 0.0f)) continue;  // a silhouette from o, or degenerate
        // (a, b, c) and (b, a, d) share a-b; the ray goes exactly through
        // `target`, strictly inside the edge.
        auto P = [&](const Vec3& p) { return p * unit + shift; };
        const Ray through_edge{P(o), (target - o) * unit, 0, kInfinity};
        const bool e1 = triangle(through_edge, P(a), P(b), P(c)), e2 = triangle(through_edge, P(b), P(a), P(d));
        ++edge_rays;
        missed += !e1 && !e2;
      }
    }
  // Vertex: a closed fan of integer triangles around a centre vertex, seen
  // from above (a height field), so the fan covers the vertex.
  for (int n = 0; n < 3000; ++n) {
    const Vec3 centre = ivec(-100, 100);
    const int k = 5 + int(irand(0, 3));
    std::vector<Vec3> ring;
    for (int i = 0; i < k; ++i) {
      const float ang = 2.0f * 3.14159265f * float(i) / float(k);
      ring.push_back(centre + Vec3{std::round(20 * std::cos(ang)), std::round(20 * std::sin(ang)), irand(-3, 3)});
    }
    const Vec3 o = centre + Vec3{irand(-20, 20), irand(-20, 20), irand(60, 120) * ((n % 2) ? 1.0f : -1.0f)};
    const Ray r{o, centre - o, 0, kInfinity};
    bool any = false;
    for (int i = 0; i < k; ++i) any |= triangle(r, centre, ring[i], ring[(i + 1) % k]);
    ++vertex_rays;
    missed += !any;
  }
  CHECK(edge_rays > 5000);
  CHECK(vertex_rays == 3000);
  CHECK(missed == 0);
}

TEST_CASE("intersect: rays through a vertex shared by a fan of triangles hit at least one of them") {
  Rng rng(4);
  std::size_t rays = 0, missed = 0;
  for (int fan = 0; fan < 50; ++fan) {
    // A gently bumpy fan of 7 triangles around a centre vertex, as a height
    // field over the xy plane; rays come from above, steeper than any slope.
    const Vec3 centre{uniform(rng, -100, 100), uniform(rng, -100, 100), uniform(rng, -1, 1)};
    Vec3 ring[7];
    for (int k = 0; k < 7; ++k) {
      const float ang = 2.0f * 3.14159265f * (float(k) + uniform(rng, -0.3f, 0.3f)) / 7.0f;
      const float r = uniform(rng, 0.5f, 2.0f);
      ring[k] = centre + Vec3{r * std::cos(ang), r * std::sin(ang), uniform(rng, -0.2f, 0.2f) * r};
    }
    for (int i = 0; i < 300; ++i) {
      const Vec3 dir_down = normalize(Vec3{uniform(rng, -0.3f, 0.3f), uniform(rng, -0.3f, 0.3f), -1.0f});
      const float sgn = (i % 2) ? 1.0f : -1.0f;  // from above and from below
      const Vec3 o = centre - dir_down * (sgn * uniform(rng, 0.5f, 50.0f));
      const Ray r{o, centre - o, 0, kInfinity};
      bool any = false;
      for (int k = 0; k < 7; ++k) any |= triangle(r, centre, ring[k], ring[(k + 1) % 7]);
      ++rays;
      missed += !any;
    }
  }
  CHECK(rays == 15000);
  CHECK(missed == 0);
}

TEST_CASE("intersect: triangles with coincident vertices never hit") {
  Rng rng(5);
  std::size_t hits = 0;
  for (int i = 0; i < 5000; ++i) {
    const Vec3 a = random_in_cube(rng, 2), b = random_in_cube(rng, 2);
    const Vec3 target = (i % 2) ? a : a + (b - a) * uniform(rng, 0, 1);
    const Vec3 o = target + random_unit(rng) * uniform(rng, 0.5f, 5.0f);
    const Ray r{o, target - o, 0, kInfinity};
    hits += triangle(r, a, a, b);  // repeated vertex
    hits += triangle(r, a, b, b);
    hits += triangle(r, b, a, b);
    hits += triangle(r, a, a, a);  // a point
  }
  CHECK(hits == 0);
}

// A triangle whose three distinct vertices are collinear: in ray space the
// projected vertices lie on a line through the origin, so the edge functions
// u, v, e are rounding noise; before the fix ~15% of the rays aimed at a
// point of the segment saw them share a sign and reported a hit.
TEST_CASE("intersect: collinear (zero-area) triangles never hit, even for rays through their segment") {
  const Vec3 tris[][3] = {{{0, 0, 0}, {1, 1, 1}, {2, 2, 2}},
                          {{-1, 0.5f, 0}, {1, 0.5f, 0}, {0, 0.5f, 0}},
                          {{0.1f, 0.2f, 0.3f}, {0.7f, 0.5f, 0.9f}, {1.3f, 0.8f, 1.5f}}};
  Rng rng(1);
  std::uniform_real_distribution<float> u01(0, 1);
  std::normal_distribution<float> n01(0, 1);
  std::size_t hits = 0;
  for (const auto& t : tris)
    for (int i = 0; i < 10000; ++i) {
      const Vec3 target = t[0] + (t[1] - t[0]) * u01(rng);
      const Vec3 o = target + Vec3{n01(rng), n01(rng), n01(rng)};
      hits += triangle(Ray{o, target - o, 0, kInfinity}, t[0], t[1], t[2]);
    }
  CHECK(hits == 0);  // before the fix: ~4600 of 30000
}

TEST_CASE("intersect: the first reproducer of the collinear-triangle bug misses") {
  const Ray r{{-0.0141240805f, -0.969165742f, 0.071623221f}, {0.148000717f, 1.10304236f, 0.0622534156f}, 0, kInfinity};
  CHECK_FALSE(triangle(r, {0, 0, 0}, {1, 1, 1}, {2, 2, 2}));
}

// The double-precision fallback of the watertight test (Woop et al. 2013,
// section 3): an edge function that rounds to exactly 0 in float is
// recomputed in double, where the products of floats are exact. Here the ray
// runs along +z through the origin, so the ray-space coordinates are the
// vertices' x and y, bit for bit, and the edge b-c passes the origin at a
// distance of ~1e-14: in float cx*by and cy*bx round to the same value (edge
// function 0, "on the edge", so the float-only test would report hits on
// BOTH triangles sharing b-c), in double the origin lies strictly on one side.
// Without the fallback the first CHECK fails.
TEST_CASE("intersect: an edge function that rounds to 0 in float is decided in double (one triangle of the pair)") {
  const float eps = std::ldexp(1.0f, -23);
  const Vec3 b{1, 1 + eps, 0}, c{-(1 + eps), -(1 + 2 * eps), 0};
  // Preconditions of the construction (the ray-space edge function of b-c at the origin).
  volatile float p = c.x * b.y, q = c.y * b.x;
  REQUIRE(p - q == 0.0f);
  REQUIRE(double(c.x) * b.y - double(c.y) * b.x < 0.0);  // exact: T1 has the origin outside b-c
  const Vec3 a{-1, 1, 0};   // T1 = (a, b, c)
  const Vec3 a2{1, -1, 0};  // T2 = (a2, c, b), the neighbour across b-c
  const Ray r{{0, 0, -1}, {0, 0, 1}, 0, kInfinity};
  TriangleHit h1, h2;
  const bool hit1 = triangle(r, a, b, c, h1), hit2 = triangle(r, a2, c, b, h2);
  CHECK_FALSE(hit1);  // float-only: hit (u == 0, v > 0, e > 0)
  CHECK(hit2);        // watertight: the neighbour takes the ray
  if (hit2) CHECK(h2.t == 1.0f);
}

// The traversal tests triangle records with the SSE form of the test
// (intersect_triangle_record); it must be the scalar test bit for bit: same
// answer, same t, same barycentrics, on random triangles, on triangles
// with integer coordinates and rays through their edges and vertices (edge
// functions exactly 0: the double fallback), and for every axis permutation.
TEST_CASE("intersect: the triangle-record (SSE) test equals the scalar test bit for bit") {
  Rng rng(11);
  std::size_t hits = 0, rays = 0, mismatches = 0;
  std::string first;
  for (int i = 0; i < 40000; ++i) {
    Primitive p;
    const bool lattice = i % 2;
    Vec3 v[3];
    for (Vec3& x : v)
      x = lattice ? Vec3{std::round(uniform(rng, -3, 3)), std::round(uniform(rng, -3, 3)), std::round(uniform(rng, -3, 3))}
                  : random_in_cube(rng, 2);
    for (int k = 0; k < 3; ++k)
      for (int a = 0; a < 3; ++a) p.data[3 * k + a] = v[k][a];
    // Aim at a vertex, an edge point or an interior point.
    const float s = uniform(rng, 0, 1), t = uniform(rng, 0, 1);
    const Vec3 target = (i % 3 == 0) ? v[(i / 3) % 3]
                  : (i % 3 == 1) ? v[0] + (v[1] - v[0]) * (lattice ? 0.5f : s)
                                 : v[0] + (v[1] - v[0]) * (s * 0.5f) + (v[2] - v[0]) * (t * 0.5f);
    const Vec3 o = lattice ? Vec3{std::round(uniform(rng, -6, 6)), std::round(uniform(rng, -6, 6)), 7.0f}
                           : target + random_unit(rng) * uniform(rng, 0.5f, 5.0f);
    const Ray r{o, target - o, (i % 5 == 0) ? 0.5f : 0.0f, (i % 7 == 0) ? 0.9f : kInfinity};
    const WatertightRay w(r.direction);
    TriangleHit hs{-1, -1, -1}, hr{-1, -1, -1};
    const bool bs = intersect_triangle(r, w, v[0], v[1], v[2], r.tmax, hs);
    const bool br = intersect_triangle_record(r, w, p.data, r.tmax, hr);
    ++rays;
    hits += bs;
    const bool same = bs == br && (!bs || (std::memcmp(&hs, &hr, sizeof hs) == 0));
    if (!same && mismatches++ == 0)
      first = "ray " + std::to_string(i) + ": scalar " + std::to_string(bs) + " t=" + std::to_string(hs.t) +
              ", record " + std::to_string(br) + " t=" + std::to_string(hr.t);
  }
  INFO(first);
  CHECK(mismatches == 0);
  CHECK(hits > rays / 4);
}

// ---------------------------------------------------------------------------
// Rays and boxes (math.h)

TEST_CASE("intersect: is_valid_ray rejects NaN, inf and zero-direction rays and a bad interval") {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = kInfinity;
  CHECK(is_valid_ray({{0, 0, 0}, {0, 0, 1}, 0, inf}));
  CHECK(is_valid_ray({{1, 2, 3}, {0, 1e-3f, 0}, 0.5f, 0.5f}));  // tmin == tmax is allowed
  CHECK(is_valid_ray({{-1e30f, 0, 0}, {1, 1, 1}, 0, 1e30f}));
  CHECK_FALSE(is_valid_ray({{0, 0, 0}, {0, 0, 0}, 0, inf}));   // zero direction
  CHECK_FALSE(is_valid_ray({{0, 0, 0}, {0, -0.0f, 0}, 0, inf}));
  CHECK_FALSE(is_valid_ray({{nan, 0, 0}, {0, 0, 1}, 0, inf}));
  CHECK_FALSE(is_valid_ray({{0, 0, 0}, {0, nan, 1}, 0, inf}));
  CHECK_FALSE(is_valid_ray({{0, inf, 0}, {0, 0, 1}, 0, inf}));
  CHECK_FALSE(is_valid_ray({{0, 0, 0}, {0, 0, -inf}, 0, inf}));
  CHECK_FALSE(is_valid_ray({{0, 0, 0}, {0, 0, 1}, nan, inf}));
  CHECK_FALSE(is_valid_ray({{0, 0, 0}, {0, 0, 1}, 0, nan}));
  CHECK_FALSE(is_valid_ray({{0, 0, 0}, {0, 0, 1}, -1, inf}));  // negative tmin
  CHECK_FALSE(is_valid_ray({{0, 0, 0}, {0, 0, 1}, 2, 1}));     // tmin > tmax
}

TEST_CASE("intersect: intersect_bounds clips rays to a box, with zero direction components") {
  const Bounds3 box{{0, 0, 0}, {1, 1, 1}};
  auto clip = [&](const Ray& r, float& t0, float& t1) {
    const Vec3 inv{1.0f / r.direction.x, 1.0f / r.direction.y, 1.0f / r.direction.z};
    return intersect_bounds(box, r, inv, t0, t1);
  };
  float t0 = 0, t1 = 0;
  REQUIRE(clip({{-1, 0.5f, 0.5f}, {1, 0, 0}, 0, kInfinity}, t0, t1));
  CHECK(t0 == 1.0f);
  CHECK(t1 >= 2.0f);
  CHECK(t1 == doctest::Approx(2.0f).epsilon(1e-5));
  CHECK_FALSE(clip({{-1, 1.5f, 0.5f}, {1, 0, 0}, 0, kInfinity}, t0, t1));  // parallel, outside the y slab
  CHECK(clip({{-1, 1.0f, 1.0f}, {1, 0, 0}, 0, kInfinity}, t0, t1));        // along an edge of the box
  CHECK_FALSE(clip({{2, 0.5f, 0.5f}, {1, 0, 0}, 0, kInfinity}, t0, t1));   // pointing away
  CHECK_FALSE(clip({{-1, 0.5f, 0.5f}, {1, 0, 0}, 0, 0.5f}, t0, t1));       // tmax before the box
  REQUIRE(clip({{0.5f, 0.5f, 0.5f}, {0, 0, -2}, 0, kInfinity}, t0, t1));   // from inside
  CHECK(t0 == 0.0f);
  CHECK(t1 == doctest::Approx(0.25f).epsilon(1e-5));
  REQUIRE(clip({{-1, -1, -1}, {1, 1, 1}, 0, kInfinity}, t0, t1));  // through two opposite corners
  CHECK(t0 == 1.0f);
  CHECK(t1 == doctest::Approx(2.0f).epsilon(1e-5));
}

TEST_CASE("intersect: geometric normals point out of spheres and cones and follow a triangle's winding") {
  Primitive s;
  s.kind = PrimitiveKind::kSphere;
  s.data[0] = 1;
  s.data[3] = 2;
  const Vec3 ns = geometric_normal(s, {1, 0, -2});
  CHECK(ns.z < 0.0f);
  CHECK(std::fabs(ns.x) + std::fabs(ns.y) < 1e-6f);

  Primitive cyl;
  cyl.kind = PrimitiveKind::kCone;
  const float cd[8] = {0, 0, 0, 1, 0, 0, 2, 1};
  std::copy(cd, cd + 8, cyl.data);
  const Vec3 nc = normalize(geometric_normal(cyl, {1, 0, 1}));
  CHECK(nc.x == doctest::Approx(1.0f));
  CHECK(nc.z == doctest::Approx(0.0f).scale(1));

  Primitive cn;
  cn.kind = PrimitiveKind::kCone;
  const float kd[8] = {0, 0, 0, 1, 0, 0, 1, 0};  // radius 1 - z
  std::copy(kd, kd + 8, cn.data);
  const Vec3 nk = normalize(geometric_normal(cn, {0.5f, 0, 0.5f}));
  CHECK(nk.x == doctest::Approx(std::sqrt(0.5f)));
  CHECK(nk.z == doctest::Approx(std::sqrt(0.5f)));

  Primitive tri;
  const float td[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  std::copy(td, td + 9, tri.data);
  const Vec3 nt = geometric_normal(tri, {0.2f, 0.2f, 0});
  CHECK(nt.z > 0.0f);
  CHECK(std::fabs(nt.x) + std::fabs(nt.y) == 0.0f);
}
