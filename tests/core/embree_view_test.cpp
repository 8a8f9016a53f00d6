// Tests of EmbreeView (core/embree_view.h): the same trace_ray and
// render_image over Embree give the grid's image — bit for bit wherever
// both accelerators hit the same primitive (Embree picks the primitive,
// raynode's own test computes t, u, v).
#include <doctest/doctest.h>

#include <cmath>
#include <cstring>

#include "core/database.h"
#include "core/direct_view.h"
#include "core/embree_scene.h"
#include "core/embree_view.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/scene_source.h"

using namespace raynode::core;

TEST_CASE("embree view: renders equal the grid's, depth, normal and colour exact where the same shape is hit") {
  for (const char* spec : {"teapot:2", "mount:1", "rings:1", "balls:1", "tetra:3"}) {
    CAPTURE(spec);
    const Scene scene = load_scene({spec, 0});
    const Database db = make_database(scene);
    const Grid grid = build_grid(db);
    const EmbreeScene embree(db);
    RenderParams p;
    p.width = p.height = 64;
    p.depth_aov = p.normal_aov = p.primitive_aov = true;
    const RenderResult g = render_image(DirectView(db, grid), db, p);
    const RenderResult e = render_image(EmbreeView(db, embree), db, p);
    REQUIRE(e.color.width == 64);
    int same_shape = 0, hits = 0, color_close = 0;
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 64; ++x) {
        const float gs = *g.primitive.at(x, y), es = *e.primitive.at(x, y);
        if (gs >= 0.0f) ++hits;
        if (gs == es) {
          ++same_shape;
          // Same first shape: the same distance and normal, to the bit.
          CHECK(std::memcmp(g.depth.at(x, y), e.depth.at(x, y), sizeof(float)) == 0);
          CHECK(std::memcmp(g.normal.at(x, y), e.normal.at(x, y), 3 * sizeof(float)) == 0);
        }
        const float* gc = g.color.at(x, y);
        const float* ec = e.color.at(x, y);
        if (std::fabs(gc[0] - ec[0]) <= 1e-4f && std::fabs(gc[1] - ec[1]) <= 1e-4f &&
            std::fabs(gc[2] - ec[2]) <= 1e-4f)
          ++color_close;
      }
    CHECK(hits > 200);                          // the scene is in view
    CHECK(same_shape >= 64 * 64 - 8);           // a few grazing pixels may differ
    CHECK(color_close >= 64 * 64 * 99 / 100);   // secondary rays may differ on a few more
    // Same rays cast (a secondary ray that differs would change these only slightly).
    CHECK(double(e.stats.rays.total()) == doctest::Approx(double(g.stats.rays.total())).epsilon(0.01));
    CHECK(e.stats.rays.primary == g.stats.rays.primary);
    // Embree's traversal reports rays only.
    CHECK(e.stats.traversal.rays == g.stats.traversal.rays);
    CHECK(e.stats.traversal.cells_visited == 0u);
    CHECK(g.stats.traversal.cells_visited > 0u);
  }
}

TEST_CASE("embree view: shared mode over Embree equals sequential mode over Embree bit for bit") {
  const Scene scene = load_scene({"rings:1", 0});
  const Database db = make_database(scene);
  const EmbreeScene embree(db);
  RenderParams p;
  p.width = p.height = 48;
  p.depth_aov = true;
  const RenderResult a = render_image(EmbreeView(db, embree), db, p);
  p.mode = RenderMode::kShared;
  const RenderResult b = render_image(EmbreeView(db, embree), db, p);
  CHECK(std::memcmp(a.color.pixels.data(), b.color.pixels.data(), a.color.pixels.size() * sizeof(float)) == 0);
  CHECK(std::memcmp(a.depth.pixels.data(), b.depth.pixels.data(), a.depth.pixels.size() * sizeof(float)) == 0);
}

TEST_CASE("embree view: closest hit is refined by raynode's own primitive test") {
  // A ray at a sphere: Embree's float sphere test and raynode's double one
  // may round differently; the view must return raynode's t.
  Scene s;
  s.add_sphere(Sphere{{0.3f, -0.2f, 0.1f}, 0.7f});
  const Vec3 tri[3] = {{-1, -1, -3}, {1, -1, -3}, {0, 1, -3}};
  s.add_polygon(tri, 3);
  const Database db = make_database(s);
  const Grid grid = build_grid(db);
  const EmbreeScene embree(db);
  TraversalScratch sg, se;
  int checked = 0;
  for (int i = 0; i < 200; ++i) {
    const float a = float(i) * 0.0137f;
    const Ray ray{{0.05f * std::cos(a * 7.0f), 0.05f * std::sin(a * 5.0f), 4.0f},
                  normalize(Vec3{0.1f * std::sin(a), 0.1f * std::cos(a * 3.0f), -1.0f}), 0.0f, kInfinity};
    Hit hg, he;
    const bool fg = intersect_closest(DirectView(db, grid), ray, hg, sg);
    const bool fe = intersect_closest(EmbreeView(db, embree), ray, he, se);
    REQUIRE(fg == fe);
    if (!fg) continue;
    REQUIRE(hg.primitive == he.primitive);
    CHECK(hg.t == he.t);  // exact: the same arithmetic
    CHECK(hg.u == he.u);
    CHECK(hg.v == he.v);
    ++checked;
    CHECK(intersect_any(EmbreeView(db, embree), Ray{ray.origin, ray.direction, 0.0f, hg.t * 1.001f}, se));
    CHECK_FALSE(intersect_any(EmbreeView(db, embree), Ray{ray.origin, ray.direction, 0.0f, hg.t * 0.999f}, se));
  }
  CHECK(checked > 150);
  CHECK(se.stats.rays == 3u * 200u - 2u * (200u - unsigned(checked)));
}
