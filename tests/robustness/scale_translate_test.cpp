// Scale and position invariance: every built-in SPD scene and a triangle
// mesh, scaled by 10^k (k = -6, -4, -2, 2, 4, 6) and moved by 10^k (every
// integer k from -6) as far as float spacing stays below 1/1000 of the
// scene's size, renders like the untransformed scene in every mode
// (sequential, shared, replicated, svm, dataflow), and the grid agrees with
// Embree on it (validate_grid). Moved scenes are rounded where they are
// moved to, then traced with the eye at the origin, as the rendering
// commands trace a file written there.
// Bounds: a scaled render may differ from the original by more than 8/255
// in some channel on at most 0.5% of its pixels, a moved one on at most 2%
// (or as much as the move's rounding of the scene alone makes it differ),
// and on at most 0.1% from the scene moved there and back.
// Also: an eye lying in a polygon's plane, coincident triangles, a 1e8
// triangle beside 1e-3 ones, an eye inside a closed sphere.
// The images are small (32 x 32) and the machines a few nodes, so that the
// whole suite takes seconds.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "core/database.h"
#include "core/embree_scene.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/scene_transform.h"
#include "core/spd.h"
#include "core/validate.h"
#include "dataflow/dataflow.h"
#include "control/replicated.h"
#include "svm/svm.h"

using namespace raynode;

namespace {

constexpr int kSize = 32;                // image width and height, pixels
constexpr float kChannelTolerance = 8.0f / 255.0f;
constexpr double kScaledBound = 0.005;   // fraction of pixels
constexpr double kMovedBound = 0.02;

/// Fraction of pixels where some channel of a and b (clamped to [0, 1], as
/// an 8-bit output stores them) differs by more than kChannelTolerance; 1
/// when the shapes differ.
double differing_fraction(const core::Image& a, const core::Image& b) {
  if (a.width != b.width || a.height != b.height || a.channels != b.channels || a.pixels.empty()) return 1.0;
  std::size_t bad = 0;
  const std::size_t n = std::size_t(a.width) * std::size_t(a.height);
  for (std::size_t p = 0; p < n; ++p)
    for (int c = 0; c < a.channels; ++c) {
      const std::size_t i = p * std::size_t(a.channels) + std::size_t(c);
      const float x = std::clamp(a.pixels[i], 0.0f, 1.0f), y = std::clamp(b.pixels[i], 0.0f, 1.0f);
      if (!(std::fabs(x - y) <= kChannelTolerance)) {
        ++bad;
        break;
      }
    }
  return double(bad) / double(n);
}

nodes::MachineParams small_machine(std::uint32_t nodes) {
  nodes::MachineParams m;
  m.nodes = nodes;
  m.node_memory = 16 * nodes::kMiB;
  m.timeout_s = 120;
  return m;
}

core::RenderParams render_params() {
  core::RenderParams rp;
  rp.width = kSize;
  rp.height = kSize;
  rp.primitive_aov = true;
  return rp;
}

/// The colour image of `db` in each of the five modes, sequential first.
std::vector<std::pair<const char*, core::Image>> render_all_modes(const core::Database& db, const core::Grid& grid) {
  std::vector<std::pair<const char*, core::Image>> out;
  const core::RenderParams rp = render_params();
  out.emplace_back("sequential", core::render(db, grid, rp).color);
#if !defined(__SANITIZE_THREAD__)
  // Shared mode runs on TBB, which ThreadSanitizer cannot see into (false
  // reports inside the uninstrumented libtbb): checked in the other builds.
  core::RenderParams shared = rp;
  shared.mode = core::RenderMode::kShared;
  shared.tile_size = 8;
  out.emplace_back("shared", core::render(db, grid, shared).color);
#endif
  control::ReplicatedParams rep;
  rep.render = rp;
  rep.machine = small_machine(3);
  out.emplace_back("replicated", control::render_replicated(db, grid, rep).render.color);
  svm::SvmParams sv;
  sv.render = rp;
  sv.machine = small_machine(3);
  sv.page_size = 256;
  out.emplace_back("svm", svm::render_svm(db, grid, sv).render.color);
  dataflow::DataflowParams df;
  df.render = rp;
  df.machine = small_machine(3);
  out.emplace_back("dataflow", dataflow::render_dataflow(db, grid, df).render.color);
  return out;
}

/// Mismatches of the grid against Embree on `db` (a small ray budget).
/// Not checked in the ThreadSanitizer build: Embree builds its scene on its
/// own TBB threads, which TSan cannot see into (false reports inside the
/// uninstrumented libembree and libtbb); the other builds check it.
std::uint64_t validate_mismatches(const core::Database& db, const core::Grid& grid) {
#if defined(__SANITIZE_THREAD__)
  (void)db;
  (void)grid;
  return 0;
#endif
  const core::EmbreeScene embree(db);
  core::ValidateParams vp;
  vp.width = kSize;
  vp.height = kSize;
  vp.random_rays = 3000;
  const core::ValidateReport r = core::validate_grid(db, grid, embree, vp);
  return r.total.mismatches();
}

/// A torus of `pp` triangles (smooth normals) over a polygon floor, with a
/// view and two lights: the "scanned mesh" of the suite.
core::Scene torus_mesh_scene() {
  core::Scene s;
  s.view.from = {3.0f, -4.0f, 3.0f};
  s.view.at = {0.0f, 0.0f, 0.3f};
  s.view.up = {0.0f, 0.0f, 1.0f};
  s.view.angle = 40.0f;
  s.view.hither = 0.5f;
  s.has_view = true;
  s.background = {0.1f, 0.2f, 0.3f};
  s.lights.push_back({{4.0f, -2.0f, 6.0f}});
  s.lights.push_back({{-3.0f, -4.0f, 4.0f}});
  s.materials.push_back({{0.8f, 0.8f, 0.7f}, 0.8f, 0.0f, 0.0f, 0.0f, 1.0f});
  const core::Vec3 floor[4] = {{-3, -3, 0}, {3, -3, 0}, {3, 3, 0}, {-3, 3, 0}};
  s.add_polygon(floor, 4);
  s.materials.push_back({{0.9f, 0.3f, 0.2f}, 0.6f, 0.3f, 30.0f, 0.0f, 1.0f});
  const int nu = 24, nv = 12;
  const double R = 1.0, r = 0.35, pi = 3.14159265358979323846;
  auto at = [&](int i, int j, core::Vec3& p, core::Vec3& n) {
    const double u = 2 * pi * i / nu, v = 2 * pi * j / nv;
    n = {float(std::cos(u) * std::cos(v)), float(std::sin(u) * std::cos(v)), float(std::sin(v))};
    p = {float((R + r * std::cos(v)) * std::cos(u)), float((R + r * std::cos(v)) * std::sin(u)),
         float(r * std::sin(v) + 0.5)};
  };
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j) {
      core::Vec3 p[4], n[4];
      at(i, j, p[0], n[0]);
      at(i + 1, j, p[1], n[1]);
      at(i + 1, j + 1, p[2], n[2]);
      at(i, j + 1, p[3], n[3]);
      const core::Vec3 t0[3] = {p[0], p[1], p[2]}, m0[3] = {n[0], n[1], n[2]};
      const core::Vec3 t1[3] = {p[0], p[2], p[3]}, m1[3] = {n[0], n[2], n[3]};
      s.add_patch(t0, m0, 3);
      s.add_patch(t1, m1, 3);
    }
  return s;
}

struct Case {
  std::string name;
  core::Scene scene;
};

/// Index (NFF shape, as the primitive AOV stores it) seen at each pixel, -1 on a miss.
std::vector<int> shapes_seen(const core::Image& primitive) {
  std::vector<int> out;
  for (float v : primitive.pixels) out.push_back(int(v));
  return out;
}

std::vector<Case> suite_scenes() {
  std::vector<Case> cases;
  for (const char* name : {"teapot", "mount", "rings", "tetra", "balls"})  // the smallest size of each
    cases.push_back({name, core::make_spd_scene(core::SpdParams{name, std::string(name) == "teapot" ? 2 : 1, 0})});
  cases.push_back({"torus mesh", torus_mesh_scene()});
  return cases;
}

/// Renders `scene` in every mode, hands each colour image to check(image)
/// (the mode captured), and checks validate.
template <class Check>
void check_every_mode(const core::Scene& scene, Check&& check) {
  const core::Database db = core::make_database(scene);
  const core::Grid grid = core::build_grid(db);
  for (const auto& [mode, image] : render_all_modes(db, grid)) {
    CAPTURE(std::string(mode));
    check(image);
  }
  CHECK(validate_mismatches(db, grid) == 0);
}

/// Renders `scene` transformed by `t` in every mode and checks each image
/// against `reference` (at most `bound` of the pixels off), and validate.
void check_transformed(const core::Scene& scene, const core::SceneTransform& t, const core::Image& reference,
                       double bound) {
  core::Scene moved = scene;
  core::transform_scene(moved, t);
  check_every_mode(moved, [&](const core::Image& image) { CHECK(differing_fraction(image, reference) <= bound); });
}

/// `scene` moved by t.translate and rounded there, then moved so that its
/// eye lies at the origin (core::eye_at_origin): as the rendering commands
/// load a file written there (`--translate` itself cancels exactly,
/// core::eye_at_origin_after, so it would test nothing of the tracer).
/// Checked in every mode against two references:
///  - the same scene moved there and back, which keeps exactly the move's
///    rounding of the scene's coordinates (its differences from the eye are
///    the moved scene's): at most 0.1% of the pixels may differ, so the
///    renderer adds nothing to that rounding;
///  - the unmoved scene's `reference`: at most kMovedBound, or, where the
///    rounding itself changes more (features finer than the spacing:
///    balls:1's smallest spheres at 1e5), no more than the round trip does.
/// Returns the round trip's difference from `reference`.
double check_moved(const core::Scene& scene, const core::SceneTransform& t, const core::Image& reference) {
  core::Scene moved = scene;
  core::transform_scene(moved, t);
  core::Scene back = moved;
  core::SceneTransform undo;
  undo.translate = {-t.translate[0], -t.translate[1], -t.translate[2]};
  core::transform_scene(back, undo);
  core::transform_scene(back, core::eye_at_origin(back));
  core::transform_scene(moved, core::eye_at_origin(moved));
  const core::Database back_db = core::make_database(back);
  const core::Image round_trip = core::render(back_db, core::build_grid(back_db), render_params()).color;
  const double rounding = differing_fraction(round_trip, reference);
  CAPTURE(rounding);
  check_every_mode(moved, [&](const core::Image& image) {
    CHECK(differing_fraction(image, round_trip) <= 0.001);
    CHECK(differing_fraction(image, reference) <= std::max(kMovedBound, rounding));
  });
  return rounding;
}

}  // namespace

/// The untransformed render; checks that the scene covers a good part of it
/// (a comparison of near-empty images would prove nothing).
core::Image reference_image(const Case& c, const core::Database& db) {
  const core::RenderResult r = core::render(db, core::build_grid(db), render_params());
  const std::vector<int> seen = shapes_seen(r.primitive);
  CAPTURE(c.name);
  CHECK(std::count_if(seen.begin(), seen.end(), [](int s) { return s >= 0; }) > int(seen.size()) / 5);
  return r.color;
}

TEST_CASE("scale invariance: every SPD scene and a mesh scaled by 1e-6 .. 1e6 render as the original in every mode") {
  for (const Case& c : suite_scenes()) {
    const core::Database db = core::make_database(c.scene);
    const core::Image reference = reference_image(c, db);
    for (int k : {-6, -4, -2, 2, 4, 6}) {
      CAPTURE(c.name);
      CAPTURE(k);
      core::SceneTransform t;
      t.scale = std::pow(10.0, k);
      check_transformed(c.scene, t, reference, kScaledBound);
    }
  }
}

TEST_CASE("position invariance: every SPD scene and a mesh moved by 10^k render as the original in every mode") {
  for (const Case& c : suite_scenes()) {
    const core::Database db = core::make_database(c.scene);
    const core::Image reference = reference_image(c, db);
    const core::Vec3 e = db.bounds.extent();
    const double size = std::max({double(e.x), double(e.y), double(e.z)});
    const double reach = std::max(double(max_component(abs(db.bounds.lower))), double(max_component(abs(db.bounds.upper))));
    int moves = 0;
    for (int k = -6;; ++k, ++moves) {
      const double shift = std::pow(10.0, k);
      // Float spacing where the moved scene lies must stay below size / 1000.
      if (std::ldexp(reach + shift, -23) >= size / 1000.0) break;
      CAPTURE(c.name);
      CAPTURE(k);
      core::SceneTransform t;
      t.translate = {shift, -0.7 * shift, 0.4 * shift};
      const double rounding = check_moved(c.scene, t, reference);
      if (rounding > kMovedBound)
        MESSAGE(c.name, " moved by 1e", k, ": its round trip alone differs on ", 100 * rounding, "% of the pixels");
    }
    CAPTURE(c.name);
    CHECK(moves >= 9);  // up to 10^2 at least: every SPD scene spans more than 1e-1
  }
}

namespace {

core::Scene open_scene(const core::Vec3& from, const core::Vec3& at, const core::Vec3& up, float angle) {
  core::Scene s;
  s.view.from = from;
  s.view.at = at;
  s.view.up = up;
  s.view.angle = angle;
  s.has_view = true;
  s.background = {0.2f, 0.3f, 0.5f};
  return s;
}

}  // namespace

TEST_CASE("eye in a polygon's plane: no eye ray hits the polygon, in any mode, and the grid agrees with Embree") {
  // Before: the grid accepted self-hits at t ~ 1e-7: speckle over the image.
  core::Scene s = open_scene({0.5f, 0.25f, 0.0f}, {0.0f, 5.0f, 0.5f}, {0, 0, 1}, 60.0f);
  s.lights.push_back({{1.0f, 2.0f, 4.0f}});
  s.materials.push_back({{0.8f, 0.8f, 0.8f}, 0.9f, 0.0f, 0.0f, 0.0f, 1.0f});
  const core::Vec3 floor[4] = {{-4, -4, 0}, {4, -4, 0}, {4, 8, 0}, {-4, 8, 0}};
  s.add_polygon(floor, 4);  // shape 0: the eye stands on it
  s.add_sphere({{0.0f, 5.0f, 0.7f}, 0.6f});
  for (double k : {1e-4, 1.0, 1e4}) {
    CAPTURE(k);
    core::Scene scaled = s;
    core::SceneTransform t;
    t.scale = k;
    core::transform_scene(scaled, t);
    const core::Database db = core::make_database(scaled);
    const core::Grid grid = core::build_grid(db);
    core::RenderParams rp = render_params();
    const core::RenderResult r = core::render(db, grid, rp);
    const std::vector<int> seen = shapes_seen(r.primitive);
    CHECK(std::count(seen.begin(), seen.end(), 0) == 0);   // the floor, at t = 0 for every ray
    CHECK(std::count(seen.begin(), seen.end(), 1) > 20);   // the sphere
    for (const auto& [mode, image] : render_all_modes(db, grid)) {
      CAPTURE(std::string(mode));
      CHECK(differing_fraction(image, r.color) == 0.0);
    }
    CHECK(validate_mismatches(db, grid) == 0);
  }
}

TEST_CASE("coincident triangles: a doubled polygon renders exactly as a single one, at any scale") {
  // The twin lies on the same plane: a shadow ray spawned from one must not
  // be blocked by the other (both reject it by the same error bound).
  core::Scene single = open_scene({1.0f, -3.0f, 2.5f}, {0.0f, 0.0f, 0.3f}, {0, 0, 1}, 50.0f);
  single.lights.push_back({{2.0f, -1.0f, 3.0f}});
  single.materials.push_back({{0.7f, 0.8f, 0.6f}, 0.8f, 0.2f, 20.0f, 0.0f, 1.0f});
  const core::Vec3 quad[4] = {{-2, -2, 0}, {2, -2.3f, 0.2f}, {2.2f, 2, 0.4f}, {-2, 2.1f, 0.1f}};
  single.add_polygon(quad, 4);
  single.add_sphere({{0.0f, 0.0f, 0.8f}, 0.5f});
  core::Scene doubled = single;
  doubled.add_polygon(quad, 4);
  for (double k : {1e-5, 1.0, 1e5}) {
    CAPTURE(k);
    core::SceneTransform t;
    t.scale = k;
    core::Scene a = single, b = doubled;
    core::transform_scene(a, t);
    core::transform_scene(b, t);
    const core::Database da = core::make_database(a), dbb = core::make_database(b);
    const core::Grid ga = core::build_grid(da), gb = core::build_grid(dbb);
    const core::Image ia = core::render(da, ga, render_params()).color;
    for (const auto& [mode, image] : render_all_modes(dbb, gb)) {
      CAPTURE(std::string(mode));
      CHECK(differing_fraction(image, ia) == 0.0);
    }
    CHECK(validate_mismatches(dbb, gb) == 0);
  }
}

TEST_CASE("a 1e8 ground triangle beside 1e-3 triangles renders as with a small ground") {
  // Small tetrahedra standing on a ground seen from 1e-2 away: the ground's
  // size must neither hide it (before: eye rays whose float t was rounding
  // noise missed it), shadow the tetrahedra nor misplace the ground's
  // shading points (a barycentric point errs by the vertices' spacing, 8).
  auto scene = [](float ground) {
    // Looking down steeply: the small ground fills the view as the huge one does.
    core::Scene s = open_scene({0.003f, -0.004f, 0.008f}, {0.0f, 0.0f, 0.0003f}, {0, 0, 1}, 50.0f);
    s.lights.push_back({{0.004f, -0.002f, 0.01f}});
    s.materials.push_back({{0.8f, 0.8f, 0.8f}, 0.9f, 0.0f, 0.0f, 0.0f, 1.0f});
    const core::Vec3 g[3] = {{-ground, -ground, 0}, {ground, -ground, 0}, {0, ground, 0}};
    s.add_polygon(g, 3);
    s.materials.push_back({{0.9f, 0.4f, 0.2f}, 0.7f, 0.3f, 30.0f, 0.0f, 1.0f});
    for (int i = 0; i < 3; ++i) {
      const float x = -0.0015f + 0.0015f * float(i), y = 0.001f * float(i % 2);
      const core::Vec3 a{x, y, 0.0f}, b{x + 0.001f, y, 0.0f}, c{x + 0.0005f, y + 0.0009f, 0.0f},
          top{x + 0.0005f, y + 0.0003f, 0.0008f};
      const core::Vec3 f0[3] = {a, b, top}, f1[3] = {b, c, top}, f2[3] = {c, a, top};
      s.add_polygon(f0, 3);
      s.add_polygon(f1, 3);
      s.add_polygon(f2, 3);
    }
    return s;
  };
  const core::Database small = core::make_database(scene(0.05f));
  const core::Image reference = core::render(small, core::build_grid(small), render_params()).color;
  const core::Database huge = core::make_database(scene(1e8f));
  const core::Grid grid = core::build_grid(huge);
  for (const auto& [mode, image] : render_all_modes(huge, grid)) {
    CAPTURE(std::string(mode));
    CHECK(differing_fraction(image, reference) <= kScaledBound);
  }
  CHECK(validate_mismatches(huge, grid) == 0);
}

TEST_CASE("eye inside a closed sphere: every eye ray sees its lit inside, at radius 1e-6 .. 1e6") {
  for (double k : {1e-6, 1.0, 1e6}) {
    CAPTURE(k);
    core::Scene s = open_scene({0.2f, -0.1f, 0.1f}, {1.0f, 0.5f, 0.0f}, {0, 0, 1}, 70.0f);
    s.lights.push_back({{-0.3f, 0.2f, 0.4f}});  // inside too
    s.materials.push_back({{0.9f, 0.7f, 0.5f}, 0.8f, 0.0f, 0.0f, 0.0f, 1.0f});
    s.add_sphere({{0.0f, 0.0f, 0.0f}, 1.0f});
    core::SceneTransform t;
    t.scale = k;
    core::transform_scene(s, t);
    const core::Database db = core::make_database(s);
    const core::Grid grid = core::build_grid(db);
    const core::RenderResult r = core::render(db, grid, render_params());
    const float ambient = 0.9f * 0.8f * 0.5f;  // red channel: colour * Kd * ambient intensity (one light)
    int lit = 0;
    for (std::size_t p = 0; p < r.primitive.pixels.size(); ++p) {
      CHECK(r.primitive.pixels[p] == 0.0f);
      lit += r.color.pixels[3 * p] > ambient + 0.05f;
    }
    CHECK(lit == int(r.primitive.pixels.size()));  // no self-shadowing anywhere
    for (const auto& [mode, image] : render_all_modes(db, grid)) {
      CAPTURE(std::string(mode));
      CHECK(differing_fraction(image, r.color) == 0.0);
    }
    CHECK(validate_mismatches(db, grid) == 0);
  }
}
