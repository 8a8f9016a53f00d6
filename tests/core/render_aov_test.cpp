// Tests of the first-hit AOVs of the renderer (core/render.h): the
// primitive AOV names the NFF shape in file order (not the triangle after
// splitting), the normal AOV is the face-forwarded shading normal, depth is
// the eye distance; misses give -1 / 0 / +inf; all modes and spp agree.
#include <doctest/doctest.h>

#include <atomic>
#include <cmath>
#include <cstring>

#include "core/camera.h"
#include "core/database.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/scene_source.h"

using namespace raynode::core;

namespace {

bool same_bits(const Image& a, const Image& b) {
  return a.width == b.width && a.height == b.height && a.channels == b.channels &&
         a.pixels.size() == b.pixels.size() &&
         std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * sizeof(float)) == 0;
}

Vec3 normal_at(const Image& im, int x, int y) {
  const float* n = im.at(x, y);
  return {n[0], n[1], n[2]};
}

/// Eye at (0, 0, 5) looking down -z, 33x33 pixels, 40 degrees: pixel
/// (16, 16) looks at the origin; column 5 at x ~ -1.25, column 27 at
/// x ~ +1.25, row 5 at y ~ +1.25 (in the plane z = 0).
///   shape 0: a triangle far outside the view
///   shape 1: a pentagon (3 triangles) around (-1.25, 0), facing +z
///   shape 2: a sphere of radius 0.5 at the origin
///   shape 3: a quad around (+1.25, 0), wound clockwise (facing -z)
///   shape 4: a `pp` quad around (0, +1.25) whose vertex normals all lean to +x
Scene aov_scene() {
  Scene s;
  s.has_view = true;
  s.view.from = {0, 0, 5};
  s.view.at = {0, 0, 0};
  s.view.up = {0, 1, 0};
  s.view.angle = 40.0f;
  s.view.width = s.view.height = 33;
  s.lights.push_back(Light{{1, 2, 10}});
  const Vec3 far_tri[3] = {{20, 20, 0}, {21, 20, 0}, {20, 21, 0}};
  s.add_polygon(far_tri, 3);
  Vec3 penta[5];
  for (int i = 0; i < 5; ++i) {
    const float a = float(i) * 2.0f * 3.14159265f / 5.0f;
    penta[i] = {-1.25f + 0.35f * std::cos(a), 0.35f * std::sin(a), 0};
  }
  s.add_polygon(penta, 5);
  s.add_sphere(Sphere{{0, 0, 0}, 0.5f});
  const Vec3 cw[4] = {{1.0f, -0.25f, 0}, {1.0f, 0.25f, 0}, {1.5f, 0.25f, 0}, {1.5f, -0.25f, 0}};
  s.add_polygon(cw, 4);
  const Vec3 pv[4] = {{-0.25f, 1.0f, 0}, {0.25f, 1.0f, 0}, {0.25f, 1.5f, 0}, {-0.25f, 1.5f, 0}};
  const Vec3 lean = normalize(Vec3{0.6f, 0.0f, 0.8f});
  const Vec3 pn[4] = {lean, lean, lean, lean};
  s.add_patch(pv, pn, 4);
  return s;
}

RenderParams all_aovs() {
  RenderParams p;
  p.depth_aov = p.normal_aov = p.primitive_aov = true;
  return p;
}

}  // namespace

TEST_CASE("render AOV: primitive is the NFF shape's file-order index, not the triangle index") {
  const Scene scene = aov_scene();
  const Database db = make_database(scene);
  // The pentagon became 3 triangles, the quads 2 each: triangle indices and
  // shape indices differ after shape 1.
  REQUIRE(db.primitives.size() == 1u + 3u + 1u + 2u + 2u);
  const Grid grid = build_grid(db);
  const RenderResult r = render(db, grid, all_aovs());
  REQUIRE(r.primitive.width == 33);
  REQUIRE(r.primitive.channels == 1);
  CHECK(*r.primitive.at(5, 16) == 1.0f);   // pentagon
  CHECK(*r.primitive.at(16, 16) == 2.0f);  // sphere
  CHECK(*r.primitive.at(18, 17) == 2.0f);
  CHECK(*r.primitive.at(27, 16) == 3.0f);  // clockwise quad: database triangles 5 and 6
  CHECK(*r.primitive.at(16, 5) == 4.0f);   // patch
  CHECK(*r.primitive.at(0, 0) == -1.0f);   // miss
  CHECK(*r.primitive.at(32, 32) == -1.0f);
  // No pixel names a shape that is not in view, or a triangle index.
  for (float v : r.primitive.pixels) CHECK((v == -1.0f || v == 1.0f || v == 2.0f || v == 3.0f || v == 4.0f));
}

TEST_CASE("render AOV: normal is the unit shading normal facing the eye, depth the eye distance") {
  const Scene scene = aov_scene();
  const Database db = make_database(scene);
  const Grid grid = build_grid(db);
  const RenderResult r = render(db, grid, all_aovs());
  REQUIRE(r.normal.channels == 3);
  // Pentagon facing +z, seen from +z.
  CHECK(normal_at(r.normal, 5, 16) == Vec3{0, 0, 1});
  // Clockwise quad faces -z; face-forwarded towards the eye it is +z.
  CHECK(normal_at(r.normal, 27, 16) == Vec3{0, 0, 1});
  // Patch: the interpolated vertex normal, not the geometric one.
  const Vec3 lean = normalize(Vec3{0.6f, 0.0f, 0.8f});
  const Vec3 pn = normal_at(r.normal, 16, 5);
  CHECK(pn.x == doctest::Approx(lean.x).epsilon(1e-6));
  CHECK(pn.y == doctest::Approx(0.0f));
  CHECK(pn.z == doctest::Approx(lean.z).epsilon(1e-6));
  // Sphere: the normal is (hit point - centre) / radius, with the hit point
  // on the centre ray at the depth AOV's distance.
  const Camera camera(render_view(db), 33, 33);
  for (auto [x, y] : {std::pair{16, 16}, {18, 17}, {14, 13}, {19, 16}}) {
    CAPTURE(x);
    CAPTURE(y);
    const Ray ray = camera.ray_through(float(x) + 0.5f, float(y) + 0.5f);
    const float t = *r.depth.at(x, y);
    const Vec3 p = ray.at(t);
    CHECK(length(p) == doctest::Approx(0.5f).epsilon(1e-5));  // depth lands on the sphere
    const Vec3 n = normal_at(r.normal, x, y);
    CHECK(length(n) == doctest::Approx(1.0f).epsilon(1e-6));
    CHECK(n.x == doctest::Approx(p.x / 0.5f).epsilon(1e-4));
    CHECK(n.y == doctest::Approx(p.y / 0.5f).epsilon(1e-4));
    CHECK(n.z == doctest::Approx(p.z / 0.5f).epsilon(1e-4));
    CHECK(dot(n, ray.direction) < 0.0f);
  }
  CHECK(*r.depth.at(16, 16) == doctest::Approx(4.5f).epsilon(1e-6));
  // Misses: zero normal, +inf depth.
  CHECK(normal_at(r.normal, 0, 0) == Vec3{0, 0, 0});
  CHECK(std::isinf(*r.depth.at(0, 0)));
}

TEST_CASE("render AOV: seen from behind, normals still face the eye") {
  Scene scene = aov_scene();
  scene.view.from = {0, 0, -5};
  const Database db = make_database(scene);
  const Grid grid = build_grid(db);
  const RenderResult r = render(db, grid, all_aovs());
  // From -z the image is mirrored in x: the pentagon is at column 27 and the quad at column 5.
  CHECK(*r.primitive.at(27, 16) == 1.0f);
  CHECK(normal_at(r.normal, 27, 16) == Vec3{0, 0, -1});
  CHECK(*r.primitive.at(5, 16) == 3.0f);
  CHECK(normal_at(r.normal, 5, 16) == Vec3{0, 0, -1});
  const Vec3 pn = normal_at(r.normal, 16, 5);
  CHECK(pn.z < 0.0f);
  CHECK(pn.x < 0.0f);  // the leaning patch normal, flipped
}

TEST_CASE("render AOV: every mode and spp give the same AOVs, the progress counter ends at width x height") {
  const Scene scene = aov_scene();
  const Database db = make_database(scene);
  const Grid grid = build_grid(db);
  RenderParams p = all_aovs();
  p.width = 40;
  p.height = 37;  // not a multiple of the tile size
  std::atomic<std::uint64_t> done{0};
  p.progress = &done;
  const RenderResult seq = render(db, grid, p);
  CHECK(done.load() == 40u * 37u);
  p.mode = RenderMode::kShared;
  done = 0;
  const RenderResult par = render(db, grid, p);
  CHECK(done.load() == 40u * 37u);
  CHECK(same_bits(seq.color, par.color));
  CHECK(same_bits(seq.depth, par.depth));
  CHECK(same_bits(seq.normal, par.normal));
  CHECK(same_bits(seq.primitive, par.primitive));
  // Even spp casts one extra centre ray: the AOVs are the same as for spp 1.
  p.spp = 2;
  p.progress = nullptr;
  const RenderResult ss = render(db, grid, p);
  CHECK(ss.stats.rays.primary == 40u * 37u * 5u);
  CHECK(same_bits(seq.depth, ss.depth));
  CHECK(same_bits(seq.normal, ss.normal));
  CHECK(same_bits(seq.primitive, ss.primitive));
  // The progress counter does not change the image.
  RenderParams q = all_aovs();
  q.width = 40;
  q.height = 37;
  CHECK(same_bits(render(db, grid, q).color, seq.color));
}

TEST_CASE("render AOV: without a request the AOV images stay empty and no extra ray is cast") {
  const Scene scene = aov_scene();
  const Database db = make_database(scene);
  const Grid grid = build_grid(db);
  RenderParams p;
  p.spp = 2;
  const RenderResult r = render(db, grid, p);
  CHECK(r.depth.empty());
  CHECK(r.normal.empty());
  CHECK(r.primitive.empty());
  CHECK(r.stats.rays.primary == 33u * 33u * 4u);
}
