// Tests for the SPD 3.14 generators gears, tree, lattice, shells, jacks and
// sombrero (core/spd_<name>.cpp). No reference file is read: every expected
// count is derived by hand from the SPD program's loops (the formula is
// written beside it) and every spot value is computed by hand (or by the
// same formula in the test) from the SPD source, e.g. gears.c's tooth
// outline or tree.c's branch matrices.
//
// Tolerance for spot values: |a - b| <= 1e-4 * max(1, |a|, |b|), as in
// spd_test.cpp (SPD prints %g, 6 significant digits).
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include "core/nff.h"
#include "core/spd.h"

namespace {

using namespace raynode::core;

constexpr double kPi = 3.141592653589793;

bool close(double a, double b, double tol = 1e-4) {
  return std::fabs(a - b) <= tol * std::max({1.0, std::fabs(a), std::fabs(b)});
}

#define CHECK_VEC(v, X, Y, Z)  \
  do {                         \
    const Vec3 v_ = (v);       \
    INFO(v_.x << " " << v_.y << " " << v_.z); \
    CHECK(close(v_.x, (X)));   \
    CHECK(close(v_.y, (Y)));   \
    CHECK(close(v_.z, (Z)));   \
  } while (0)

Scene make(const std::string& name, int size, int tessellate = 0) {
  return make_spd_scene(SpdParams{name, size, tessellate});
}

SceneCounts counts(std::size_t polygons, std::size_t patches, std::size_t spheres,
                   std::size_t cones, std::size_t lights, std::size_t materials) {
  SceneCounts c;
  c.polygons = polygons;
  c.patches = patches;
  c.spheres = spheres;
  c.cones = cones;
  c.lights = lights;
  c.materials = materials;
  return c;
}

// Vertex k of shape i (a polygon or patch).
Vec3 vertex(const Scene& s, std::size_t i, std::uint32_t k) {
  REQUIRE(i < s.shapes.size());
  REQUIRE(k < s.shapes[i].count);
  return s.vertices[s.shapes[i].first + k];
}

const Sphere& sphere(const Scene& s, std::size_t i) {
  REQUIRE(i < s.shapes.size());
  REQUIRE(s.shapes[i].kind == ShapeKind::kSphere);
  return s.spheres[s.shapes[i].first];
}

const Cone& cone(const Scene& s, std::size_t i) {
  REQUIRE(i < s.shapes.size());
  REQUIRE(s.shapes[i].kind == ShapeKind::kCone);
  return s.cones[s.shapes[i].first];
}

void check_material(const Material& m, double r, double g, double b, double kd, double ks,
                    double shine, double t, double ior) {
  CHECK_VEC(m.color, r, g, b);
  CHECK(close(m.kd, kd));
  CHECK(close(m.ks, ks));
  CHECK(close(m.shine, shine));
  CHECK(close(m.transmittance, t));
  CHECK(close(m.ior, ior));
}

// SPD lib_output_color's Phong exponent for a half-angle in degrees.
double phong(double deg) { return std::log(0.5) / std::log(std::cos(deg * kPi / 180.0)); }

// write_nff then parse_nff gives back the same scene, entity for entity and
// bit for bit (the writer's numbers round-trip floats).
void check_round_trip(const Scene& scene) {
  std::ostringstream out;
  write_nff(out, scene);
  const Scene back = parse_nff(out.str());
  CHECK(back.counts() == scene.counts());
  CHECK(back.dropped_degenerate == 0);
  CHECK(back.has_view == scene.has_view);
  CHECK(back.view == scene.view);
  CHECK(back.background == scene.background);
  CHECK(back.lights == scene.lights);
  CHECK(back.materials == scene.materials);
  REQUIRE(back.shapes.size() == scene.shapes.size());
  std::size_t differing = 0;
  for (std::size_t i = 0; i < scene.shapes.size(); ++i) {
    const Shape& a = scene.shapes[i];
    const Shape& b = back.shapes[i];
    bool same = a.kind == b.kind && a.count == b.count && a.material == b.material;
    if (same && (a.kind == ShapeKind::kPolygon || a.kind == ShapeKind::kPatch)) {
      for (std::uint32_t k = 0; k < a.count; ++k) {
        same = same && scene.vertices[a.first + k] == back.vertices[b.first + k];
        if (a.kind == ShapeKind::kPatch) {
          same = same && scene.normals[a.first_normal + k] == back.normals[b.first_normal + k];
        }
      }
    } else if (same && a.kind == ShapeKind::kSphere) {
      same = scene.spheres[a.first] == back.spheres[b.first];
    } else if (same && a.kind == ShapeKind::kCone) {
      same = scene.cones[a.first] == back.cones[b.first];
    }
    if (!same) ++differing;
  }
  CHECK(differing == 0);
}

}  // namespace

// ---------------------------------------------------------------- gears

TEST_CASE("spd gears: counts are 1 + 146 s^3 polygons and 1 + s^3 materials") {
  // gears.c: a ground square, then per gear (s^3 of them) a 144-vertex top
  // (4 points x 36 teeth), 144 side rectangles and a 144-vertex bottom.
  CHECK(make("gears", 1).counts() == counts(1 + 146, 0, 0, 0, 5, 1 + 1));
  CHECK(make("gears", 2).counts() == counts(1 + 146 * 8, 0, 0, 0, 5, 1 + 8));
  CHECK(make("gears", -1).counts() == counts(1 + 146 * 64, 0, 0, 0, 5, 1 + 64));  // -s 4
  const Scene g = make("gears", 2);
  CHECK(g.shapes[1].count == 144);
  CHECK(g.shapes[2].count == 4);
  CHECK(g.shapes[146].count == 144);
}

TEST_CASE("spd gears: size 1 view, ground, tooth outline and glassy first gear as gears.c computes") {
  const Scene g = make("gears", 1);
  CHECK(g.has_view);
  CHECK_VEC(g.view.from, -1.1, -2.1, 2.6);
  CHECK_VEC(g.view.at, 0, 0, 0);
  CHECK_VEC(g.view.up, 0, 0, 1);
  CHECK(g.view.angle == 45.0f);
  CHECK(g.view.hither == 1.0f);
  CHECK(g.view.width == 512);
  CHECK_VEC(g.background, 0.078, 0.361, 0.753);
  CHECK_VEC(g.lights[4].position, -1.111, -2.121, 2.626);
  check_material(g.materials[0], 1, 0.85, 0.7, 0.3, 0.6, phong(37.0), 0, 0);  // 3.0827
  CHECK_VEC(vertex(g, 0, 1), -2, 2, 0);
  // Gear colour (0.01 + frac(5/7), 0.01 + frac(3/7), 0.01 + frac(2/7)) over its
  // largest channel; (4x + 2y + z) % 5 == 0, so kd 0.2, T 0.8, ior 1.1.
  check_material(g.materials[1], 1, 0.43857142857 / 0.72428571429, 0.29571428571 / 0.72428571429,
                 0.2, 0, 100000, 0.8, 1.1);
  // Outer radius 1 / (1 - 0) = 1, centre (0, 0, 1), tooth 10 degrees: the top
  // starts at 0.995 (cos, sin)(-0.19 * 10 deg), then +0.19 tooth, then 0.9 at
  // 0.3 and 0.7 tooth.
  const double t = 2.0 * kPi / 36.0;
  CHECK_VEC(vertex(g, 1, 0), 0.995 * std::cos(0.19 * t), -0.995 * std::sin(0.19 * t), 1.0);
  CHECK_VEC(vertex(g, 1, 1), 0.995 * std::cos(0.19 * t), 0.995 * std::sin(0.19 * t), 1.0);
  CHECK_VEC(vertex(g, 1, 2), 0.9 * std::cos(0.3 * t), 0.9 * std::sin(0.3 * t), 1.0);
  CHECK_VEC(vertex(g, 1, 7), 0.9 * std::cos(1.7 * t), 0.9 * std::sin(1.7 * t), 1.0);
  CHECK_VEC(vertex(g, 1, 0), 0.994453, -0.0329894, 1.0);  // as SPD prints it
  // First side: top point 0, down by the thickness min(0.1, 1/2), then point 1.
  CHECK_VEC(vertex(g, 2, 1), 0.994453, -0.0329894, 0.9);
  CHECK_VEC(vertex(g, 2, 2), 0.994453, 0.0329894, 0.9);
  CHECK_VEC(vertex(g, 2, 3), 0.994453, 0.0329894, 1.0);
  // The last side closes the outline (point 143 back to point 0).
  CHECK_VEC(vertex(g, 145, 3), 0.994453, -0.0329894, 1.0);
  // Bottom: teeth clockwise, so it starts at +0.19 tooth, z = 1 - 0.1.
  CHECK_VEC(vertex(g, 146, 0), 0.994453, 0.0329894, 0.9);
  CHECK_VEC(vertex(g, 146, 2), 0.9 * std::cos(0.3 * t), -0.9 * std::sin(0.3 * t), 0.9);
  CHECK(g.shapes[146].material == 1);
}

TEST_CASE("spd gears: size 2 places the second gear one pitch along X, half a tooth turned, diffuse") {
  const Scene g = make("gears", 2);
  // Outer radius 1 / (2 - 0.1 / 2) = 1/1.95, pitch r (2 - 0.1), first centre -1 + r.
  const double r = 1.0 / 1.95;
  const double cx = -1.0 + r + r * 1.9, cy = -1.0 + r;
  const double t = 2.0 * kPi / 36.0;
  const double a = kPi / 36.0 - 0.19 * t;  // (ix + iy + iz) % 2 == 1: offset pi / 36
  // Gear (ix 1, iy 0, iz 0) starts at shape 1 + 146.
  CHECK_VEC(vertex(g, 147, 0), cx + 0.995 * r * std::cos(a), cy + 0.995 * r * std::sin(a), 1.0);
  // Its colour: (0.01 + frac(4 * 5/7), 0.01 + frac(2 * 3/7), 0.01 + frac(3 * 2/7)), (4 % 5 != 0): kd 1.
  const double c[3] = {0.01 + 20.0 / 7.0 - 2.0, 0.01 + 6.0 / 7.0, 0.01 + 6.0 / 7.0};
  const double m = std::max({c[0], c[1], c[2]});
  check_material(g.materials[2], c[0] / m, c[1] / m, c[2] / m, 1.0, 0, 100000, 0, 0);
  // The second layer (iz 1, after 4 gears) sits 1/2 lower.
  CHECK(close(vertex(g, 1 + 146 * 4, 0).z, 0.5));
}

// ---------------------------------------------------------------- tree

TEST_CASE("spd tree: counts are 2^(s+1) - 1 cones and spheres, one field, 7 lights") {
  // tree.c grow_tree: one cone + sphere per call, two calls below each
  // call of depth > 0, depth from s down to 0: 2^(s+1) - 1 calls.
  CHECK(make("tree", 1).counts() == counts(1, 0, 3, 3, 7, 2));
  CHECK(make("tree", 3).counts() == counts(1, 0, 15, 15, 7, 2));
  CHECK(make("tree", -1).counts() == counts(1, 0, 4095, 4095, 7, 2));  // -s 11
}

TEST_CASE("spd tree: trunk and first two branches follow tree.c's branch matrices") {
  const Scene t = make("tree", 1);
  CHECK_VEC(t.view.from, 4.5, 0.4, 2.0);
  CHECK_VEC(t.view.at, 0, 0, 1.5);
  CHECK_VEC(t.lights[6].position, -10, -60, 30);
  check_material(t.materials[0], 0.2, 0.7, 0.2, 1, 0, 100000, 0, 0);
  check_material(t.materials[1], 0.55, 0.4, 0.2, 1, 0, 100000, 0, 0);
  CHECK_VEC(vertex(t, 0, 0), 50, 50, 0);
  // Trunk: the unit Z segment, radius 0.15 tapering by 0.67, sphere at the top.
  const Cone& trunk = cone(t, 1);
  CHECK_VEC(trunk.base, 0, 0, 0);
  CHECK_VEC(trunk.apex, 0, 0, 1);
  CHECK(close(trunk.base_radius, 0.15));
  CHECK(close(trunk.apex_radius, 0.1005));
  CHECK_VEC(sphere(t, 2).center, 0, 0, 1);
  CHECK(close(sphere(t, 2).radius, 0.1005));
  // First branch: rotate 40 deg about X, 90 deg about Z, scale 0.65, up 1:
  // (0,0,1) -> (0, -sin 40, cos 40) -> (sin 40, 0, cos 40) -> 0.65 x + (0,0,1).
  const double s40 = std::sin(40.0 * kPi / 180), c40 = std::cos(40.0 * kPi / 180);
  const Cone& b0 = cone(t, 3);
  CHECK_VEC(b0.base, 0, 0, 1);
  CHECK_VEC(b0.apex, 0.65 * s40, 0, 1 + 0.65 * c40);
  CHECK(close(b0.base_radius, 0.1005));
  CHECK(close(b0.apex_radius, 0.1005 * 0.67));
  CHECK(t.shapes[3].material == 1);
  // Second branch: 25 deg about X, 230 deg about Z, scale 0.7.
  const double s25 = std::sin(25.0 * kPi / 180), c25 = std::cos(25.0 * kPi / 180);
  const double c230 = std::cos(230.0 * kPi / 180), s230 = std::sin(230.0 * kPi / 180);
  const Cone& b1 = cone(t, 5);
  CHECK_VEC(b1.apex, 0.7 * s25 * s230, -0.7 * s25 * c230, 1 + 0.7 * c25);
  CHECK_VEC(b1.apex, -0.226621, 0.190158, 1.634416);
  CHECK_VEC(sphere(t, 6).center, -0.226621, 0.190158, 1.634416);
}

// ---------------------------------------------------------------- lattice

TEST_CASE("spd lattice: counts are (s+1)^3 spheres, 3 s (s+1)^2 cylinders, one f before each") {
  // lattice.c: a sphere at every (x, y, z) in 0..s, and a cylinder towards
  // +X, +Y, +Z unless on that face; each with its own lib_output_color.
  CHECK(make("lattice", 1).counts() == counts(0, 0, 8, 12, 6, 8 + 12));
  CHECK(make("lattice", 2).counts() == counts(0, 0, 27, 54, 6, 27 + 54));
  CHECK(make("lattice", -1).counts() == counts(0, 0, 2197, 6084, 6, 2197 + 6084));  // -s 12
}

TEST_CASE("spd lattice: view, sphere, cylinder inset and materials as lattice.c computes") {
  const Scene l = make("lattice", 2);
  // from (((2 >> 1) + 0.5) / 2, 1, 1 - 1/4), at (0.75, -1, -1 - 1/4), up (0.2, 1, 0).
  CHECK_VEC(l.view.from, 0.75, 1.0, 0.75);
  CHECK_VEC(l.view.at, 0.75, -1.0, -1.25);
  CHECK_VEC(l.view.up, 0.2, 1.0, 0.0);
  CHECK(l.view.angle == 60.0f);
  CHECK(l.view.hither == 0.0f);
  CHECK_VEC(l.lights[5].position, 0.5, 0.5, -1.0);
  check_material(l.materials[0], 0.9, 0.9, 0.9, 0.5, 0.5, phong(37.0), 0, 0);
  check_material(l.materials[1], 0.9, 0.1, 0.1, 0.99, 0, 100000, 0, 0);
  check_material(l.materials[3], 0.1, 0.1, 0.9, 0.99, 0, 100000, 0, 0);
  // Radii 1/4 / 2 and 1/16 / 2; inset (0.125 (1 - sqrt(1/4))) 0.99 = 0.061875.
  CHECK_VEC(sphere(l, 0).center, 0, 0, 0);
  CHECK(close(sphere(l, 0).radius, 0.125));
  const Cone& x = cone(l, 1);
  CHECK_VEC(x.base, 0.061875, 0, 0);
  CHECK_VEC(x.apex, 0.5 - 0.061875, 0, 0);
  CHECK(close(x.base_radius, 0.03125));
  CHECK(close(x.apex_radius, 0.03125));
  CHECK(l.shapes[1].material == 1);
  CHECK_VEC(cone(l, 3).apex, 0, 0, 0.5 - 0.061875);
  CHECK(l.shapes[3].material == 3);
  // (0, 0, 2) is on the z face: a sphere then +X and +Y cylinders only, so
  // the shape after it is (0, 1, 0)'s sphere: shapes 0..3, 4..7, 8..10, 11.
  CHECK_VEC(sphere(l, 8).center, 0, 0, 1);
  CHECK_VEC(sphere(l, 11).center, 0, 0.5, 0);
  // The far corner (2, 2, 2) is last and alone.
  CHECK_VEC(sphere(l, l.shapes.size() - 1).center, 1, 1, 1);
  // Size 1's view: x = (0 + 0.5) / 1.
  CHECK_VEC(make("lattice", 1).view.from, 0.5, 1.0, 0.5);
}

// ---------------------------------------------------------------- shells

TEST_CASE("spd shells: counts are steps/3 + 2 steps/3 + 1 spheres, steps = 180 2^s") {
  // shells.c: for (i = -steps*2/3; i <= steps/3; ++i), C integer division.
  CHECK(make("shells", 1).counts() == counts(0, 0, 120 + 240 + 1, 0, 1, 1));
  CHECK(make("shells", 2).counts() == counts(0, 0, 240 + 480 + 1, 0, 1, 1));
  CHECK(make("shells", -1).counts() == counts(0, 0, 1920 + 3840 + 1, 0, 1, 1));  // -s 5
}

TEST_CASE("spd shells: the spiral r = exp(0.15 angle), z = -2 r, from angle -12 pi to 6 pi") {
  const Scene s = make("shells", 1);
  CHECK_VEC(s.view.from, -6, -60, 35);
  CHECK_VEC(s.view.at, 0, 8, -15);
  CHECK(s.view.hither == 0.5f);
  CHECK_VEC(s.lights[0].position, -100, -100, 100);
  check_material(s.materials[0], 1, 0.8, 0.4, 0.8, 0.2, phong(10.0), 0, 1);
  // i = -240 of 360: angle 18 pi (-240/360) = -12 pi.
  const double r0 = std::exp(-0.15 * 12.0 * kPi);
  const Sphere& first = sphere(s, 0);
  CHECK(first.center.x == doctest::Approx(0.0).epsilon(1e-9));
  CHECK(first.center.y == doctest::Approx(r0).epsilon(1e-6));
  CHECK(first.center.z == doctest::Approx(-2.0 * r0).epsilon(1e-6));
  CHECK(first.radius == doctest::Approx(r0).epsilon(1e-6));
  // i = 120: angle 6 pi, r = exp(0.9 pi) = 16.9188.
  const double r1 = std::exp(0.9 * kPi);
  const Sphere& last = sphere(s, 360);
  CHECK_VEC(last.center, 0, r1, -2 * r1);
  CHECK(close(last.radius, r1));
  // i = -239: angle -12 pi + pi/20.
  const double a = 18.0 * kPi * -239.0 / 360.0, r = std::exp(0.15 * a);
  CHECK(sphere(s, 1).center.x == doctest::Approx(r * std::sin(a)).epsilon(1e-6));
  CHECK(sphere(s, 1).center.y == doctest::Approx(r * std::cos(a)).epsilon(1e-6));
}

// ---------------------------------------------------------------- jacks

TEST_CASE("spd jacks: counts are 3 J cones and 6 J spheres, J = (8^s - 1) / 7 jacks") {
  // jacks.c make_rec_jack: a jack, and below max depth eight half-size copies.
  CHECK(make("jacks", -1).counts() == counts(0, 0, 6, 3, 1, 1));  // -s 1
  CHECK(make("jacks", 2).counts() == counts(0, 0, 6 * 9, 3 * 9, 1, 1));
  CHECK(make("jacks", 3).counts() == counts(0, 0, 6 * 73, 3 * 73, 1, 1));
}

TEST_CASE("spd jacks: the jack is scaled 0.75 and turned -20 deg about Y then -30 deg about X") {
  const Scene j = make("jacks", 1);
  CHECK_VEC(j.background, 0.2, 0.05, 0.2);
  CHECK_VEC(j.view.from, 0, 0, -8);
  CHECK_VEC(j.view.up, 0, 1, 0);
  CHECK(j.view.angle == 25.0f);
  CHECK(j.view.hither == 0.001f);
  CHECK(j.view.width == 256);
  CHECK(j.view.height == 256);
  CHECK_VEC(j.lights[0].position, -10, 3, -20);
  check_material(j.materials[0], 0.737, 0.561, 0.561, 0.7, 0.7, phong(20.0), 0, 1);
  // (-0.75, 0, 0): about Y by -20 deg -> (-0.75 cos 20, 0, -0.75 sin 20), then
  // about X by -30 deg -> (x, z sin 30, z cos 30) (SPD's row-vector matrices).
  const double c20 = std::cos(20 * kPi / 180), s20 = std::sin(20 * kPi / 180);
  const double z = -0.75 * s20;
  const Cone& x_axis = cone(j, 0);
  CHECK_VEC(x_axis.base, -0.75 * c20, z * 0.5, z * std::cos(30 * kPi / 180));
  CHECK(close(x_axis.base_radius, 0.075));
  CHECK(close(x_axis.apex_radius, 0.075));
  CHECK_VEC(x_axis.apex, 0.75 * c20, -z * 0.5, -z * std::cos(30 * kPi / 180));
  // Spheres radius 0.2 x 0.75; the first at +X, the fourth at -X.
  CHECK(close(sphere(j, 3).radius, 0.15));
  CHECK_VEC(sphere(j, 3).center, 0.75 * c20, -z * 0.5, -z * std::cos(30 * kPi / 180));
  CHECK_VEC(sphere(j, 6).center, -0.75 * c20, z * 0.5, z * std::cos(30 * kPi / 180));
  // Unrotated, +Y would be (0, 0.75, 0): about X by -30 deg it is
  // (0, 0.75 cos 30, -0.75 sin 30).
  CHECK_VEC(sphere(j, 4).center, 0, 0.75 * std::cos(30 * kPi / 180), -0.75 * 0.5);
}

TEST_CASE("spd jacks: size 2's first copy is half size at octant (-0.5, -0.5, -0.5)") {
  const Scene j = make("jacks", 2);
  // Shapes 0..8 are the big jack; 9..17 the copy at (-.5,-.5,-.5), radius
  // 0.2 x 0.75 x 0.5, its +X sphere at ((1 x 0.75) 0.5 + (-0.5, -0.5, -0.5)) rotated.
  CHECK(close(cone(j, 9).base_radius, 0.0375));
  CHECK(close(sphere(j, 12).radius, 0.075));
  // Unrotated centre (-0.125, -0.5, -0.5): about Y by -20 deg, then X by -30 deg.
  const double c20 = std::cos(20 * kPi / 180), s20 = std::sin(20 * kPi / 180);
  const double c30 = std::cos(30 * kPi / 180), s30 = 0.5;
  const double px = -0.125, py = -0.5, pz = -0.5;
  const double yx = px * c20 + pz * -s20, yz = -px * -s20 + pz * c20;  // about Y by -20
  const double ry = py * c30 - yz * -s30, rz = py * -s30 + yz * c30;    // about X by -30
  CHECK_VEC(sphere(j, 12).center, yx, ry, rz);
}

TEST_CASE("spd jacks: -t tessellates each jack in its own frame, as SPD under its transform stack") {
  const Scene curved = make("jacks", 1);
  const Scene j = make("jacks", 1, 1);
  // 3 cones x 8 then 6 spheres x 12 triangles, in the curved shapes' order.
  REQUIRE(j.counts() == counts(0, 3 * 8 + 6 * 12, 0, 0, 1, 1));
  CHECK(j.view == curved.view);
  CHECK(j.materials == curved.materials);
  // Undo the root turn (about Y by -20 deg, then X by -30 deg): inverse
  // about X by +30 deg, then Y by +20 deg.
  const auto unturn = [](const Vec3& p) {
    const double c30 = std::cos(30 * kPi / 180), s30 = 0.5;
    const double c20 = std::cos(20 * kPi / 180), s20 = std::sin(20 * kPi / 180);
    const double y = p.y * c30 - p.z * s30, z = p.y * s30 + p.z * c30;  // about X by +30
    return Vec3{static_cast<float>(p.x * c20 + z * s20), static_cast<float>(y),
                static_cast<float>(-p.x * s20 + z * c20)};  // about Y by +20
  };
  for (std::size_t i = 24; i < j.shapes.size(); ++i) {
    const Sphere& s = sphere(curved, 3 + (i - 24) / 12);
    for (std::uint32_t k = 0; k < 3; ++k) {
      const Vec3 d = vertex(j, i, k) - s.center;
      CHECK(length(d) == doctest::Approx(0.15).epsilon(1e-5));
      // R = 1: the grid points are the corners of the jack's own cube, so in
      // the jack's frame |x| = |y| = |z| (a world-space grid would not turn).
      const Vec3 l = unturn(d);
      CHECK(std::fabs(l.x) == doctest::Approx(std::fabs(l.y)).epsilon(1e-4));
      CHECK(std::fabs(l.x) == doctest::Approx(std::fabs(l.z)).epsilon(1e-4));
      // SPD moves normals by the inverse transpose, unnormalised: 1 / 0.75 long.
      CHECK(length(j.normals[j.shapes[i].first_normal + k]) ==
            doctest::Approx(1.0 / 0.75).epsilon(1e-5));
    }
  }
}

// ---------------------------------------------------------------- sombrero

TEST_CASE("spd sombrero: counts are 2 (W-1)^2 triangles, W = 32 2^(s-1)") {
  // lib_output_polygon_height: two triangles per cell of the W x W samples.
  CHECK(make("sombrero", -1).counts() == counts(2 * 31 * 31, 0, 0, 0, 1, 1));  // -s 1
  CHECK(make("sombrero", 2).counts() == counts(2 * 63 * 63, 0, 0, 0, 1, 1));
  const Scene s = make("sombrero", 1);
  for (const Shape& sh : s.shapes) CHECK(sh.count == 3);
}

TEST_CASE("spd sombrero: heights sampled with step 8/W, placed with step 8/(W-1), y = -3 + h") {
  const Scene s = make("sombrero", 1);
  CHECK_VEC(s.view.from, 0, 5, -8);
  CHECK(s.view.angle == 40.0f);
  CHECK(s.view.hither == 0.01f);
  CHECK_VEC(s.lights[0].position, 10, 10, -10);
  check_material(s.materials[0], 1, 0.1, 0.1, 0.8, 0, phong(40.0), 0, 1);
  // SPD's height: 3 cos(2 pi' r) exp(-r) / 3 with pi' = 3.14159265358.
  const auto h = [](double x, double y) {
    const double r = std::sqrt(x * x + y * y);
    return 3.0 * std::cos(2.0 * 3.14159265358 * r) * std::exp(-r) / 3.0;
  };
  const double step = 8.0 / 31.0;
  // Cell (row 0, column 0): (corner, far, right), then (corner, up, far).
  CHECK_VEC(vertex(s, 0, 0), -4, -3.00193, -4);
  CHECK_VEC(vertex(s, 0, 1), -4 + step, -3.00164, -4 + step);
  CHECK_VEC(vertex(s, 1, 1), -4, -3.00413, -4 + step);
  CHECK_VEC(vertex(s, 1, 2), -4 + step, -3.00164, -4 + step);
  // The height at column 1 is sampled at x = -4 + 8/32, not at -4 + 8/31.
  CHECK(vertex(s, 0, 2).y + 3.0 == doctest::Approx(h(-3.75, -4.0)).epsilon(1e-5));
  // Cell (row 15, column 15), triangle 2 (15 * 31 + 15): its corner is the
  // sample at x = y = -4 + 15/4 = -0.25, placed at -4 + 15 * 8/31.
  const Vec3 c = vertex(s, 2 * (15 * 31 + 15), 0);
  CHECK(close(c.x, -4 + 15 * step));
  CHECK(close(c.z, -4 + 15 * step));
  CHECK(c.y + 3.0 == doctest::Approx(h(-0.25, -0.25)).epsilon(1e-5));
}

// ---------------------------------------------------------------- all six

TEST_CASE("spd more: -t R turns spheres into 12 R^2 and cones into 8 R triangles, polygons kept") {
  // tree:1 has 3 cones and 3 spheres; lattice:1 8 spheres and 12 cones;
  // shells:1 361 spheres; jacks:1 6 spheres and 3 cones.
  CHECK(make("tree", 1, 1).counts() == counts(1, 3 * 8 + 3 * 12, 0, 0, 7, 2));
  CHECK(make("tree", 1, 2).counts() == counts(1, 3 * 16 + 3 * 48, 0, 0, 7, 2));
  CHECK(make("lattice", 1, 1).counts() == counts(0, 8 * 12 + 12 * 8, 0, 0, 6, 20));
  CHECK(make("shells", 1, 1).counts() == counts(0, 361 * 12, 0, 0, 1, 1));
  CHECK(make("jacks", 1, 2).counts() == counts(0, 6 * 48 + 3 * 16, 0, 0, 1, 1));
  CHECK(make("jacks", 2, 1).counts() == counts(0, 9 * (6 * 12 + 3 * 8), 0, 0, 1, 1));
  // No curved primitives: unchanged.
  CHECK(make("gears", 1, 3).counts() == make("gears", 1).counts());
  CHECK(make("sombrero", 1, 3).counts() == make("sombrero", 1).counts());
}

TEST_CASE("spd more: scene write output read back (core NFF reader) is the same scene") {
  for (const char* name : {"gears", "tree", "lattice", "shells", "jacks", "sombrero"}) {
    INFO(name);
    check_round_trip(make(name, 2));
  }
  check_round_trip(make("tree", 2, 1));
  check_round_trip(make("jacks", 2, 2));
}

TEST_CASE("spd more: sizes outside each generator's range are refused, naming the range") {
  const std::pair<const char*, int> ranges[] = {{"gears", 20},  {"tree", 20},  {"lattice", 80},
                                                {"shells", 14}, {"jacks", 7}, {"sombrero", 6}};
  for (const auto& [name, max_size] : ranges) {
    INFO(name);
    const std::string message =
        std::string(name) + ": size 0 is out of range 1.." + std::to_string(max_size);
    CHECK_THROWS_WITH_AS(make(name, 0), doctest::Contains(message.c_str()), std::invalid_argument);
    CHECK_THROWS_AS(make(name, max_size + 1), std::invalid_argument);
    CHECK(parse_spd_spec(std::string(name) + ":3").size == 3);
  }
  // jacks' own -t path refuses what tessellate_scene refuses.
  CHECK_THROWS_AS(make("jacks", 1, -1), std::invalid_argument);
  CHECK_THROWS_WITH_AS(make("jacks", 7, 10), doctest::Contains("more than the 33554432 supported"),
                       std::invalid_argument);
}
