// Tests of the shading rules of core/shade.h that the render tests do not
// pin down: Snell's law and total internal reflection for T > 0, and which
// ray kinds the SPD scenes' materials cast (skip what a scene does not need).
#include <doctest/doctest.h>

#include <cmath>

#include "core/database.h"
#include "core/direct_view.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/scene_source.h"
#include "core/shade.h"

using namespace raynode::core;

namespace {

constexpr float kPi = 3.14159265358979f;

/// Direction hitting the plane y = 0 from above at `deg` degrees from the normal (0, 1, 0).
Vec3 incident(float deg) {
  const float a = deg * kPi / 180.0f;
  return {std::sin(a), -std::cos(a), 0.0f};
}

/// A glass sphere (radius 1 at the origin: Kd = Ks = 0, T = 1, ior 1.5),
/// no lights, background (0.2, 0.3, 0.4).
Scene glass_ball() {
  Scene s;
  s.background = {0.2f, 0.3f, 0.4f};
  Material glass;
  glass.kd = 0.0f;
  glass.ks = 0.0f;
  glass.transmittance = 1.0f;
  glass.ior = 1.5f;
  s.materials.push_back(glass);
  s.add_sphere(Sphere{{0, 0, 0}, 1.0f});
  return s;
}

}  // namespace

TEST_CASE("shade: refract obeys Snell's law and reports total internal reflection past the critical angle") {
  const Vec3 n{0, 1, 0};
  for (float deg : {0.0f, 10.0f, 30.0f, 60.0f, 85.0f}) {
    CAPTURE(deg);
    Vec3 t;
    REQUIRE(refract(incident(deg), n, 1.0f / 1.5f, t));  // air -> glass: always refracts
    CHECK(length(t) == doctest::Approx(1.0f).epsilon(1e-6));
    CHECK(t.y < 0.0f);  // goes through
    CHECK(t.x >= 0.0f);
    CHECK(t.z == 0.0f);
    // n1 sin(theta_i) = n2 sin(theta_t)
    CHECK(1.0f * std::sin(deg * kPi / 180.0f) == doctest::Approx(1.5f * t.x).epsilon(1e-5));
  }
  // Glass -> air: critical angle asin(1 / 1.5) = 41.81 degrees.
  Vec3 t{9, 9, 9};
  CHECK(refract(incident(41.0f), n, 1.5f, t));
  CHECK(1.5f * std::sin(41.0f * kPi / 180.0f) == doctest::Approx(t.x).epsilon(1e-4));
  t = {9, 9, 9};
  CHECK_FALSE(refract(incident(42.5f), n, 1.5f, t));
  CHECK(t == Vec3{9, 9, 9});  // untouched on TIR
  CHECK_FALSE(refract(incident(80.0f), n, 1.5f, t));
}

TEST_CASE("shade: a ray inside a glass ball beyond the critical angle is trapped by total internal reflection") {
  const Scene s = glass_ball();
  const Database db = make_database(s);
  const Grid grid = build_grid(db);
  const ShadingContext ctx = make_shading_context(db, 5);
  {
    // Hits the wall at cos(theta) = sqrt(1 - 0.81) = 0.436, 64 degrees > 41.8:
    // every bounce has the same angle (a sphere), so it never gets out.
    ShadingScratch scratch;
    const Vec3 c = trace_ray(DirectView(db, grid), ctx, Ray{{0.9f, 0, 0}, {0, 1, 0}}, 1, 1.0f, scratch);
    CHECK(c == Vec3{0, 0, 0});  // no light, no escape: black
    CHECK(scratch.stats.rays.refracted == 4u);  // levels 2..5
    CHECK(scratch.stats.rays.refracted_tir == 4u);
    CHECK(scratch.stats.skipped.depth_limit == 1u);
    CHECK(scratch.stats.rays.reflected == 0u);
  }
  {
    // Near normal incidence: refracts out and sees the background, weight T = 1.
    ShadingScratch scratch;
    const Vec3 c = trace_ray(DirectView(db, grid), ctx, Ray{{0.1f, 0, 0}, {0, 1, 0}}, 1, 1.0f, scratch);
    CHECK(c.x == doctest::Approx(0.2f));
    CHECK(c.y == doctest::Approx(0.3f));
    CHECK(c.z == doctest::Approx(0.4f));
    CHECK(scratch.stats.rays.refracted == 1u);
    CHECK(scratch.stats.rays.refracted_tir == 0u);
  }
  {
    // From outside, through the ball: enter and exit (2 refracted rays), no TIR
    // (a sphere never traps a ray that entered it).
    ShadingScratch scratch;
    const Vec3 c = trace_ray(DirectView(db, grid), ctx, Ray{{0.7f, -5, 0}, {0, 1, 0}}, 1, 1.0f, scratch);
    CHECK(scratch.stats.rays.refracted == 2u);
    CHECK(scratch.stats.rays.refracted_tir == 0u);
    CHECK(c.z == doctest::Approx(0.4f));
  }
}

TEST_CASE("shade: the SPD scenes cast only the ray kinds their materials need") {
  RenderParams p;
  p.width = p.height = 48;
  {
    // tetra: Kd only (Ks = 0, T = 0): primary and shadow rays, nothing else.
    const Database db = make_database(load_scene({"tetra:4", 0}));
    const Grid grid = build_grid(db);
    const RenderResult r = render(db, grid, p);
    CHECK(r.stats.rays.total() == r.stats.rays.primary + r.stats.rays.shadow);
    CHECK(r.stats.rays.shadow > 0u);
    CHECK(r.stats.skipped.reflection_ks0 > 0u);
    CHECK(r.stats.skipped.refraction_t0 == r.stats.skipped.reflection_ks0);
    CHECK(r.stats.skipped.highlight_marker == 0u);  // Ks = 0: no highlight to skip
    CHECK(r.stats.skipped.depth_limit == 0u);
    CHECK(r.stats.skipped.min_weight == 0u);
  }
  {
    // rings: Ks > 0, T = 0: reflected rays, never refracted ones.
    const Database db = make_database(load_scene({"rings:1", 0}));
    const Grid grid = build_grid(db);
    const RenderResult r = render(db, grid, p);
    CHECK(r.stats.rays.reflected > 0u);
    CHECK(r.stats.rays.refracted == 0u);
    CHECK(r.stats.skipped.refraction_t0 > 0u);
  }
  {
    // mount: the glass ball (T = 0.9, ior 1.5) refracts. A chord of a sphere
    // meets its surface at the same angle at both ends, so a ray refracted
    // into the curved ball never meets total internal reflection (the few
    // that an absolute spawn offset once produced were rounding artefacts);
    // the tessellated ball's flat facets do reflect some totally.
    p.width = p.height = 128;
    for (int tessellate : {0, 1}) {
      CAPTURE(tessellate);
      const Database db = make_database(load_scene({"mount:1", tessellate}));
      bool has_glass = false;
      for (const Material& m : db.materials) has_glass |= m.transmittance > 0.0f;
      REQUIRE(has_glass);
      const Grid grid = build_grid(db);
      const RenderResult r = render(db, grid, p);
      CHECK(r.stats.rays.refracted > 0u);
      if (tessellate == 0) CHECK(r.stats.rays.refracted_tir == 0u);
      else CHECK(r.stats.rays.refracted_tir > 0u);
      CHECK(r.stats.rays.refracted_tir < r.stats.rays.refracted);
    }
  }
}
