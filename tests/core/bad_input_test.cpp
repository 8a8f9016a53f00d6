// Bad input at the core's boundary: what the NFF reader, the
// default camera and the Embree oracle do with inputs that used to crash,
// hang, allocate without bound or fail with a message naming neither the
// place nor the numbers. Every case here was a real failure first; the fuzz
// target (fuzz/nff_fuzzer.cpp) adds its crashing inputs to this file.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "core/camera.h"
#include "core/database.h"
#include "core/embree_scene.h"
#include "core/grid.h"
#include "core/nff.h"
#include "core/render.h"

using namespace raynode::core;

namespace {

/// Parses `text`; returns the ParseError's "line:col: message" ("" if it parsed).
std::string error_of(const std::string& text) {
  try {
    parse_nff(text, "bad.nff");
  } catch (const ParseError& e) {
    return std::to_string(e.line()) + ":" + std::to_string(e.column()) + ": " + e.message();
  }
  return "";
}

std::string view(const char* from, const char* at, const char* up, const char* angle = "45",
                 const char* resolution = "8 8") {
  return std::string("v\nfrom ") + from + "\nat " + at + "\nup " + up + "\nangle " + angle + "\nhither 0\nresolution " +
         resolution + "\ns 0 0 0 1\n";
}

}  // namespace

TEST_CASE("bad input: a view the camera cannot use is a parse error at its label, with the numbers") {
  // Before: read fine, then the renderer stopped with "view 'from' and 'at'
  // are the same point" (no file, no line, exit status 2 as for a bad flag).
  CHECK(error_of(view("1 2 3", "1 2 3", "0 0 1")) == "3:1: view 'at' (1, 2, 3) is the same point as 'from'");
  CHECK(error_of(view("0 0 5", "0 0 0", "0 0 2")) ==
        "4:1: view 'up' (0, 0, 2) is parallel to the viewing direction (0, 0, -5)");
  CHECK(error_of(view("0 0 5", "0 0 0", "0 0 0")).rfind("4:1: view 'up' (0, 0, 0) is parallel", 0) == 0);
  CHECK(error_of(view("0 0 5", "0 0 0", "0 1 0", "0")) == "5:1: view 'angle' 0 must be in (0, 180) degrees");
  CHECK(error_of(view("0 0 5", "0 0 0", "0 1 0", "180")) == "5:1: view 'angle' 180 must be in (0, 180) degrees");
  CHECK(error_of(view("0 0 5", "0 0 0", "0 1 0", "-30")) == "5:1: view 'angle' -30 must be in (0, 180) degrees");
  // 'from' and 'at' so far apart that their difference overflows float.
  CHECK(error_of(view("-3e38 0 0", "3e38 0 0", "0 0 1")).rfind("3:1: view 'at' (3e+38, 0, 0) is too far from", 0) == 0);
  // The checks hold whatever order the labels come in.
  CHECK(error_of("v\nresolution 8 8\nup 0 1 0\nat 1 1 1\nangle 45\nhither 0\nfrom 1 1 1\n") ==
        "4:1: view 'at' (1, 1, 1) is the same point as 'from'");
  // And a good view still parses, and its camera builds.
  const Scene s = parse_nff(view("0 0 5", "0 0 0", "0 1 0"));
  CHECK(s.has_view);
  CHECK_NOTHROW(Camera(s.view, 8, 8));
}

TEST_CASE("bad input: a view resolution above 16384 is refused at the number instead of allocating it") {
  // Before: `resolution 100000 100000` read fine and `render` died of std::bad_alloc (120 GB of pixels).
  CHECK(error_of(view("0 0 5", "0 0 0", "0 1 0", "45", "100000 100000")) ==
        "7:12: resolution width 100000 is above the 16384 pixels supported");
  CHECK(error_of(view("0 0 5", "0 0 0", "0 1 0", "45", "16384 16385")) ==
        "7:18: resolution height 16385 is above the 16384 pixels supported");
  CHECK(error_of(view("0 0 5", "0 0 0", "0 1 0", "45", "16384 16384")) == "");
}

TEST_CASE("bad input: binary garbage is quoted as \\xNN in the message, never as raw bytes") {
  const std::string garbage = std::string("\x01\xff\xfe", 3) + " 1 2\n";
  CHECK(error_of(garbage) == "1:1: unknown keyword '\\x01\\xff\\xfe'");
  const std::string tab_in_token = std::string("p\x1b[2J 3\n");
  CHECK(error_of(tab_in_token) == "1:1: unknown keyword 'p\\x1b[2J'");
}

TEST_CASE("bad input: huge vertex counts are refused or cost only the vertices present") {
  CHECK(error_of("p 1000000000\n0 0 0\n") == "1:3: polygon has 1000000000 vertices; at most 10000000 are supported");
  CHECK(error_of("p 9000000\n0 0 0\n1 0 0\n") == "4:1: file ends inside a 'p' entity (expected 8999998 more vertices)");
  CHECK(error_of("pp 99999999999999999999\n") == "1:4: patch vertex count '99999999999999999999' is out of range");
  for (const char* n : {"0", "1", "2", "-3"})
    CHECK(error_of(std::string("p ") + n + "\n0 0 0\n1 0 0\n0 1 0\n") ==
          std::string("1:3: polygon has ") + n + " vertices; at least 3 are needed");
}

TEST_CASE("bad input: a scene without a view whose bounds overflow float gets a message, not a NaN camera") {
  // Before: from = at + offset * inf gave a NaN camera and the misleading
  // "view 'up' is parallel to the viewing direction" (exit status 2).
  const Database db = make_database(parse_nff("s 3e38 0 0 1\ns -3e38 0 0 1\n"));
  try {
    render_view(db);
    FAIL("render_view must throw");
  } catch (const std::runtime_error& e) {
    CHECK(std::string(e.what()).find("reaches too far for a default camera") != std::string::npos);
  }
  // Large but representable bounds (|extent|^2 overflows float) still get a camera that sees the scene.
  const Database ok = make_database(parse_nff("s 1e30 0 0 1e29\ns -1e30 0 0 1e29\n"));
  const View v = render_view(ok);
  CHECK(is_finite(v.from));
  const Camera cam(v, 3, 3);
  const Ray centre = cam.ray_through(1.5f, 1.5f);
  CHECK(is_finite(centre.direction));
  CHECK(length(centre.direction) == doctest::Approx(1.0f));
  CHECK(dot(centre.direction, normalize_any(v.at - v.from)) > 0.999f);  // the centre ray looks at the centre
}

TEST_CASE("bad input: a camera farther than 1.8e19 from its target still aims at it (|from - at|^2 overflows float)") {
  // Before: normalize(at - from) gave a zero vector and Camera threw "view 'up' is parallel".
  const Scene s = parse_nff("v\nfrom 0 0 1e30\nat 0 0 0\nup 0 1 0\nangle 45\nhither 0\nresolution 3 3\ns 0 0 0 1e29\n");
  const Camera cam(s.view, 3, 3);
  const Ray r = cam.ray_through(1.5f, 1.5f);
  CHECK(r.direction.x == 0.0f);
  CHECK(r.direction.y == 0.0f);
  CHECK(r.direction.z == -1.0f);
  // normalize_any equals normalize where |a|^2 is a normal float, bit for bit.
  for (const Vec3 a : {Vec3{1, 2, 3}, Vec3{-0.3f, 1e-3f, 7}, Vec3{1e18f, -2e18f, 3e17f}})
    CHECK(normalize_any(a) == normalize(a));
  const Vec3 n = normalize_any(Vec3{3e30f, 0, -4e30f});  // normalize() gives (0, 0, 0) here
  CHECK(n.x == doctest::Approx(0.6f));
  CHECK(n.y == 0.0f);
  CHECK(n.z == doctest::Approx(-0.8f));
  CHECK(length(normalize_any(Vec3{1e-30f, 1e-30f, 0})) == doctest::Approx(1.0f));
}

TEST_CASE("bad input: Embree refuses rays beyond its range with a message instead of aborting") {
  // Before: `raynode validate` on a scene reaching 1e38 died of an assertion
  // inside Embree (RayK::valid(): |origin|, |direction| <= 1.844e18).
  const Database db = make_database(parse_nff("s 0 0 0 1\n"));
  const EmbreeScene embree(db);
  Hit hit;
  CHECK(embree.intersect_closest(Ray{{0, 0, -5}, {0, 0, 1}, 0.0f, kInfinity}, hit));
  CHECK(hit.t == doctest::Approx(4.0f));
  const Ray far{{1e38f, 0, 0}, {-1, 0, 0}, 0.0f, kInfinity};
  CHECK_THROWS_WITH_AS(embree.intersect_closest(far, hit), doctest::Contains("Embree cannot trace a ray from (1e+38"),
                       std::domain_error);
  CHECK_THROWS_AS(embree.intersect_any(far), std::domain_error);
  const Ray nan_interval{{0, 0, -5}, {0, 0, 1}, 0.0f, std::numeric_limits<float>::quiet_NaN()};
  CHECK_THROWS_AS(embree.intersect_any(nan_interval), std::domain_error);
}

TEST_CASE("bad input (fuzz): a triangle 1e-40 wide renders without converting a huge cell index to int") {
  // nff_fuzzer, clang -fsanitize=undefined: "traverse.h:205: -1.49012e+16 is
  // outside the range of representable values of type 'int'" (cells of
  // 1e-41, a ray entering the grid a rounding error outside it). The same
  // conversion in build_grid's cell ranges. Fixed with clamped_floor.
  const Scene s = parse_nff("b 1e-45 -0 +0.5\n# a comment\n#another\np 3 0 0 0 1e-40 0 0 0 1e-40 0\n");
  const Database db = make_database(s);
  REQUIRE(db.primitives.size() == 1);
  const Grid grid = build_grid(db);
  RenderParams rp;
  rp.width = rp.height = 3;
  rp.max_depth = 3;
  const RenderResult r = render(db, grid, rp);
  REQUIRE(r.color.pixels.size() == 27);
  for (float c : r.color.pixels) CHECK(std::isfinite(c));
  CHECK(r.stats.rays.primary == 9);
}

TEST_CASE("bad input (fuzz): a tiny scene far from the origin without a view gets a camera that looks at it") {
  // nff_fuzzer (CI, stop 19): "view 'up' is parallel to the viewing
  // direction" from render() of an accepted scene. The default camera stood
  // 1.5 diagonals (0.39) from a 0.07-radius sphere at x = 6.5e6, where floats
  // are 0.5 apart: 'from' rounded onto 'at' in x and y, leaving a viewing
  // direction straight down, parallel to 'up'.
  const Database db = make_database(parse_nff("#0.7 743431 0\ns 6495310 3172546 .7250 0.07412\n"));
  const View v = render_view(db);
  const Vec3 oblique = normalize(Vec3{-0.3f, 0.4f, -0.866f});  // the default camera's viewing direction
  CHECK(dot(normalize_any(v.at - v.from), oblique) > 0.9999f);
  CHECK_NOTHROW(Camera(v, 3, 3));
  const Grid grid = build_grid(db);
  RenderParams rp;
  rp.width = rp.height = 3;
  const RenderResult r = render(db, grid, rp);
  CHECK(r.stats.rays.primary == 9);
  // A scene near the origin keeps its camera 1.5 bounds diagonals away.
  const Database near = make_database(parse_nff("s 100 0 0 1\n"));
  const View nv = render_view(near);
  CHECK(length(nv.from - nv.at) == doctest::Approx(1.5f * length(near.bounds.extent())).epsilon(1e-4));
}

TEST_CASE("bad input: clamped_floor clamps before converting, NaN and infinities included") {
  CHECK(clamped_floor(2.5, 10) == 2);
  CHECK(clamped_floor(-0.5, 10) == 0);
  CHECK(clamped_floor(9.99, 10) == 9);
  CHECK(clamped_floor(1e30, 10) == 9);
  CHECK(clamped_floor(-1.49012e16, 10) == 0);
  CHECK(clamped_floor(std::numeric_limits<double>::infinity(), 4) == 3);
  CHECK(clamped_floor(-std::numeric_limits<double>::infinity(), 4) == 0);
  CHECK(clamped_floor(std::numeric_limits<double>::quiet_NaN(), 4) == 0);
  CHECK(clamped_floor(0.0, 1) == 0);
  // The float overload (the 3D-DDA's) gives the same answers.
  CHECK(clamped_floor(2.5f, 10) == 2);
  CHECK(clamped_floor(-0.5f, 10) == 0);
  CHECK(clamped_floor(9.99f, 10) == 9);
  CHECK(clamped_floor(1e30f, 10) == 9);
  CHECK(clamped_floor(std::numeric_limits<float>::infinity(), 4) == 3);
  CHECK(clamped_floor(-std::numeric_limits<float>::infinity(), 4) == 0);
  CHECK(clamped_floor(std::numeric_limits<float>::quiet_NaN(), 4) == 0);
}
