// Tests of the Whitted renderer (core/render.h, core/shade.h): modes agree
// bit for bit, ray counts follow the materials, depth AOV and background.
#include <doctest/doctest.h>

#include <cmath>
#include <cstring>

#include "core/database.h"
#include "core/direct_view.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/scene_source.h"

using namespace raynode::core;

namespace {

RenderResult render_spec(const std::string& spec, RenderMode mode, int size, int spp = 1, bool depth = false) {
  const Scene scene = load_scene({spec, 0});
  const Database db = make_database(scene);
  const Grid grid = build_grid(db);
  RenderParams p;
  p.width = p.height = size;
  p.spp = spp;
  p.mode = mode;
  p.depth_aov = depth;
  return render(db, grid, p);
}

bool same_bits(const Image& a, const Image& b) {
  return a.width == b.width && a.height == b.height && a.channels == b.channels &&
         a.pixels.size() == b.pixels.size() &&
         std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * sizeof(float)) == 0;
}

/// A square quad in the plane z = 0, side 2*half, centred at (cx, cy), facing +z.
void add_quad(Scene& s, float cx, float cy, float half) {
  const Vec3 v[4] = {{cx - half, cy - half, 0}, {cx + half, cy - half, 0}, {cx + half, cy + half, 0},
                     {cx - half, cy + half, 0}};
  s.add_polygon(v, 4);
}

/// Eye at (0, 0, dist) looking down -z at the origin, 33x33 pixels.
Scene looking_down(float dist) {
  Scene s;
  s.has_view = true;
  s.view.from = {0, 0, dist};
  s.view.at = {0, 0, 0};
  s.view.up = {0, 1, 0};
  s.view.angle = 40.0f;
  s.view.width = s.view.height = 33;
  s.background = {0.2f, 0.3f, 0.4f};
  s.lights.push_back(Light{{1, 2, 10}});
  return s;
}

}  // namespace

TEST_CASE("render: sequential and shared modes give bit-identical images (teapot:2, rings:1)") {
  for (const char* spec : {"teapot:2", "rings:1"}) {
    CAPTURE(spec);
    const RenderResult seq = render_spec(spec, RenderMode::kSequential, 48, 1, true);
    const RenderResult par = render_spec(spec, RenderMode::kShared, 48, 1, true);
    CHECK(same_bits(seq.color, par.color));
    CHECK(same_bits(seq.depth, par.depth));
    CHECK(seq.stats.rays.primary == par.stats.rays.primary);
    CHECK(seq.stats.rays.shadow == par.stats.rays.shadow);
    CHECK(seq.stats.rays.reflected == par.stats.rays.reflected);
    CHECK(seq.stats.rays.refracted == par.stats.rays.refracted);
    CHECK(seq.stats.rays.primary == 48u * 48u);
    // The image is not trivially constant.
    float lo = 1e30f, hi = -1e30f;
    for (float v : seq.color.pixels) lo = std::min(lo, v), hi = std::max(hi, v);
    CHECK(hi - lo > 0.1f);
  }
  // Supersampled too (2x2 fixed offsets).
  const RenderResult a = render_spec("teapot:2", RenderMode::kSequential, 20, 2);
  const RenderResult b = render_spec("teapot:2", RenderMode::kShared, 20, 2);
  CHECK(same_bits(a.color, b.color));
  CHECK(a.stats.rays.primary == 20u * 20u * 4u);
}

TEST_CASE("render: tetra (Ks = 0, T = 0) casts only primary and shadow rays and counts the skips") {
  const Scene scene = load_scene({"tetra:2", 0});
  const Database db = make_database(scene);
  for (const Material& m : db.materials) {
    REQUIRE(m.ks == 0.0f);
    REQUIRE(m.transmittance == 0.0f);
  }
  const RenderResult r = render_spec("tetra:2", RenderMode::kSequential, 40);
  CHECK(r.stats.rays.primary == 40u * 40u);
  CHECK(r.stats.rays.shadow > 0u);
  CHECK(r.stats.rays.reflected == 0u);
  CHECK(r.stats.rays.refracted == 0u);
  CHECK(r.stats.skipped.reflection_ks0 > 0u);
  CHECK(r.stats.skipped.refraction_t0 == r.stats.skipped.reflection_ks0);  // one of each per hit
  CHECK(r.stats.traversal.triangle_tests > 0u);
  CHECK(r.stats.traversal.cells_visited > 0u);
}

TEST_CASE("render: --shadow-rays all casts a shadow ray to every light, facing or not, and draws the same image") {
  // rings:1 has three lights, a mirror and cylinders lit from behind on one side: every kind of ray.
  for (const char* spec : {"rings:1", "teapot:2"}) {
    CAPTURE(spec);
    const Scene scene = load_scene({spec, 0});
    const Database db = make_database(scene);
    const Grid grid = build_grid(db);
    RenderParams p;
    p.width = p.height = 40;
    const RenderResult facing = render(db, grid, p);
    p.shadow_rays = ShadowRays::kAll;
    const RenderResult all = render(db, grid, p);
    REQUIRE(facing.stats.skipped.shadow_backfacing > 0u);  // the scene has lights behind some surfaces
    CHECK(all.stats.skipped.shadow_backfacing == 0u);
    CHECK(all.stats.rays.shadow == facing.stats.rays.shadow + facing.stats.skipped.shadow_backfacing);
    CHECK(all.stats.rays.primary == facing.stats.rays.primary);
    CHECK(all.stats.rays.reflected == facing.stats.rays.reflected);
    CHECK(all.stats.rays.refracted == facing.stats.rays.refracted);
    CHECK(all.stats.skipped.highlight_marker == facing.stats.skipped.highlight_marker);
    CHECK(all.stats.traversal.rays > facing.stats.traversal.rays);  // the extra rays were traced
    CHECK(same_bits(all.color, facing.color));
  }
}

TEST_CASE("render: a mirror (Ks > 0) casts reflected rays, max depth and min weight stop them") {
  Scene s = looking_down(5.0f);
  Material mirror;
  mirror.color = {0.5f, 0.5f, 0.5f};
  mirror.kd = 0.5f;
  mirror.ks = 0.5f;
  mirror.shine = 100000.0f;
  s.materials.push_back(mirror);
  add_quad(s, 0, 0, 1.0f);
  const Database db = make_database(s);
  const Grid grid = build_grid(db);
  RenderParams p;
  const RenderResult r = render(db, grid, p);
  CHECK(r.stats.rays.reflected > 0u);
  CHECK(r.stats.rays.refracted == 0u);
  CHECK(r.stats.skipped.highlight_marker > 0u);  // Shine 100000 with Ks > 0
  // Each reflected ray leaves the quad upwards and misses: one per quad hit.
  CHECK(r.stats.rays.reflected == r.stats.skipped.refraction_t0);
  // The reflected background adds Ks * background to the centre pixel.
  const float* c = r.color.at(16, 16);
  p.max_depth = 1;
  const RenderResult flat = render(db, grid, p);
  CHECK(flat.stats.rays.reflected == 0u);
  CHECK(flat.stats.skipped.depth_limit == r.stats.rays.reflected);
  const float* f = flat.color.at(16, 16);
  CHECK(c[2] - f[2] == doctest::Approx(0.5f * 0.4f).epsilon(1e-5));
  p.max_depth = 5;
  p.min_weight = 0.6f;
  const RenderResult pruned = render(db, grid, p);
  CHECK(pruned.stats.rays.reflected == 0u);
  CHECK(pruned.stats.skipped.min_weight == r.stats.rays.reflected);
}

TEST_CASE("render: depth AOV at the image centre is the distance to a quad at known distance") {
  for (float dist : {3.0f, 7.5f}) {
    CAPTURE(dist);
    Scene s = looking_down(dist);
    add_quad(s, 0, 0, 0.5f);
    const Database db = make_database(s);
    const Grid grid = build_grid(db);
    for (int spp : {1, 2}) {
      RenderParams p;
      p.depth_aov = true;
      p.spp = spp;
      const RenderResult r = render(db, grid, p);
      REQUIRE(r.depth.width == 33);
      CHECK(*r.depth.at(16, 16) == doctest::Approx(dist).epsilon(1e-6));
      CHECK(std::isinf(*r.depth.at(0, 0)));  // corner ray misses the small quad
    }
  }
}

TEST_CASE("render: a ray that misses everything gets the background colour") {
  Scene s = looking_down(5.0f);
  add_quad(s, 10.0f, 10.0f, 0.5f);  // far outside the view
  const Database db = make_database(s);
  const Grid grid = build_grid(db);
  const RenderResult r = render(db, grid, RenderParams{});
  for (int y = 0; y < 33; y += 8)
    for (int x = 0; x < 33; x += 8) {
      const float* c = r.color.at(x, y);
      CHECK(c[0] == 0.2f);
      CHECK(c[1] == 0.3f);
      CHECK(c[2] == 0.4f);
    }
  CHECK(r.stats.rays.shadow == 0u);
  // And trace_ray directly, away from the quad.
  ShadingScratch scratch;
  FirstHit first{1.0f, {1, 0, 0}, 7};
  const Vec3 c = trace_ray(DirectView(db, grid), make_shading_context(db), Ray{{0, 0, 5}, {0, 0, 1}}, 1, 1.0f,
                           scratch, &first);
  CHECK(c == Vec3{0.2f, 0.3f, 0.4f});
  CHECK(std::isinf(first.t));
  CHECK(first.shape == -1);
  CHECK(first.normal == Vec3{0, 0, 0});
}

TEST_CASE("render: a lit diffuse quad seen head-on has ambient + Lambert colour with SPD intensities") {
  Scene s = looking_down(5.0f);
  s.lights[0].position = {0, 0, 10};  // straight above the centre
  Material m;
  m.color = {1.0f, 0.5f, 0.25f};
  m.kd = 0.8f;
  s.materials.push_back(m);
  add_quad(s, 0, 0, 1.0f);
  const Database db = make_database(s);
  const Grid grid = build_grid(db);
  const RenderResult r = render(db, grid, RenderParams{});
  // One light: I = sqrt(1)/(2*1) = 0.5 for the light and the ambient; N.L = 1 at the centre.
  const float* c = r.color.at(16, 16);
  CHECK(c[0] == doctest::Approx(0.8f * 0.5f + 0.8f * 0.5f).epsilon(1e-5));
  CHECK(c[1] == doctest::Approx(0.5f * (0.8f * 0.5f + 0.8f * 0.5f)).epsilon(1e-5));
  // Seen from behind (two-sided shading): the light is then on the far side -> ambient only.
  Scene back = s;
  back.view.from = {0, 0, -5};
  const Database db2 = make_database(back);
  const Grid grid2 = build_grid(db2);
  const RenderResult rb = render(db2, grid2, RenderParams{});
  CHECK(rb.color.at(16, 16)[0] == doctest::Approx(0.8f * 0.5f).epsilon(1e-5));
  CHECK(rb.stats.skipped.shadow_backfacing > 0u);
}
