// Tests for the built-in SPD generators mount, rings, tetra, balls and the -t
// tessellation: every non-teapot reference file in ../shared/scenes/spd
// (written by Eric Haines' SPD 3.14) is regenerated and compared entity by
// entity. The teapot is tested in spd_teapot_test.cpp.
//
// Tolerance: two numbers match when |a - b| <= 1e-4 * max(1, |a|, |b|), i.e.
// 1e-4 relative for magnitudes above 1 and 1e-4 absolute below. The reference
// files print %g (6 significant digits), so a correct generator lands within
// ~5e-6 relative; values that are zero in exact arithmetic (SPD prints e.g.
// 1.11022e-16) compare absolutely.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/nff.h"
#include "core/scene_source.h"
#include "core/scene_transform.h"
#include "core/spd.h"
#include "scenes_dir.h"

namespace {

using namespace raynode::core;

constexpr double kTolerance = 1e-4;

double deviation(double a, double b) {
  return std::fabs(a - b) / std::max({1.0, std::fabs(a), std::fabs(b)});
}

// Walks two scenes in file order and records the largest deviation and the
// first few mismatches (structure or numbers beyond kTolerance).
struct SceneDiff {
  double max_deviation = 0.0;
  std::size_t mismatches = 0;
  std::vector<std::string> first;  // up to 5 descriptions

  void note(const std::string& what) {
    if (first.size() < 5) first.push_back(what);
    ++mismatches;
  }
  void number(double got, double want, const std::string& where) {
    const double d = deviation(got, want);
    max_deviation = std::max(max_deviation, d);
    if (!(d <= kTolerance)) {
      std::ostringstream s;
      s << where << ": got " << got << ", reference " << want;
      note(s.str());
    }
  }
  void vec(const Vec3& got, const Vec3& want, const std::string& where) {
    number(got.x, want.x, where + ".x");
    number(got.y, want.y, where + ".y");
    number(got.z, want.z, where + ".z");
  }
  std::string report() const {
    std::ostringstream s;
    s << mismatches << " mismatches, max deviation " << max_deviation;
    for (const std::string& f : first) s << "\n  " << f;
    return s.str();
  }
};

SceneDiff compare_scenes(const Scene& got, const Scene& want) {
  SceneDiff diff;
  if (got.has_view != want.has_view) diff.note("has_view differs");
  diff.vec(got.view.from, want.view.from, "view.from");
  diff.vec(got.view.at, want.view.at, "view.at");
  diff.vec(got.view.up, want.view.up, "view.up");
  diff.number(got.view.angle, want.view.angle, "view.angle");
  diff.number(got.view.hither, want.view.hither, "view.hither");
  if (got.view.width != want.view.width || got.view.height != want.view.height) {
    diff.note("view resolution differs");
  }
  diff.vec(got.background, want.background, "background");

  if (got.lights.size() != want.lights.size()) diff.note("light count differs");
  for (std::size_t i = 0; i < std::min(got.lights.size(), want.lights.size()); ++i) {
    const std::string where = "light " + std::to_string(i);
    diff.vec(got.lights[i].position, want.lights[i].position, where);
    if (got.lights[i].has_color != want.lights[i].has_color) diff.note(where + " colour flag");
  }

  if (got.materials.size() != want.materials.size()) diff.note("material count differs");
  for (std::size_t i = 0; i < std::min(got.materials.size(), want.materials.size()); ++i) {
    const Material& g = got.materials[i];
    const Material& w = want.materials[i];
    const std::string where = "material " + std::to_string(i);
    diff.vec(g.color, w.color, where + ".color");
    diff.number(g.kd, w.kd, where + ".kd");
    diff.number(g.ks, w.ks, where + ".ks");
    diff.number(g.shine, w.shine, where + ".shine");
    diff.number(g.transmittance, w.transmittance, where + ".T");
    diff.number(g.ior, w.ior, where + ".ior");
  }

  if (got.shapes.size() != want.shapes.size()) diff.note("shape count differs");
  const std::size_t n = std::min(got.shapes.size(), want.shapes.size());
  for (std::size_t i = 0; i < n && diff.mismatches < 100; ++i) {
    const Shape& g = got.shapes[i];
    const Shape& w = want.shapes[i];
    const std::string where = "shape " + std::to_string(i);
    if (g.kind != w.kind || g.count != w.count || g.material != w.material) {
      diff.note(where + ": kind, vertex count or material differs");
      continue;
    }
    switch (g.kind) {
      case ShapeKind::kPolygon:
      case ShapeKind::kPatch:
        for (std::uint32_t k = 0; k < g.count; ++k) {
          diff.vec(got.vertices[g.first + k], want.vertices[w.first + k],
                   where + " vertex " + std::to_string(k));
          if (g.kind == ShapeKind::kPatch) {
            diff.vec(got.normals[g.first_normal + k], want.normals[w.first_normal + k],
                     where + " normal " + std::to_string(k));
          }
        }
        break;
      case ShapeKind::kSphere: {
        const Sphere& gs = got.spheres[g.first];
        const Sphere& ws = want.spheres[w.first];
        diff.vec(gs.center, ws.center, where + " centre");
        diff.number(gs.radius, ws.radius, where + " radius");
        break;
      }
      case ShapeKind::kCone: {
        const Cone& gc = got.cones[g.first];
        const Cone& wc = want.cones[w.first];
        diff.vec(gc.base, wc.base, where + " base");
        diff.number(gc.base_radius, wc.base_radius, where + " base radius");
        diff.vec(gc.apex, wc.apex, where + " apex");
        diff.number(gc.apex_radius, wc.apex_radius, where + " apex radius");
        break;
      }
    }
  }
  return diff;
}

struct Reference {
  const char* file;
  const char* name;
  int size;
  int tessellate;
};

// Every non-teapot file of spd/MANIFEST.tsv, with the SPD command that wrote it.
constexpr Reference kReferences[] = {
    {"mount-s1.nff", "mount", 1, 0},      {"mount-s1-t1.nff", "mount", 1, 1},
    {"mount-s6.nff", "mount", 6, 0},      {"mount-s6-t6.nff", "mount", 6, 6},
    {"rings-s1.nff", "rings", 1, 0},      {"rings-s1-t1.nff", "rings", 1, 1},
    {"rings-s3-t1.nff", "rings", 3, 1},   {"rings-s4.nff", "rings", 4, 0},
    {"rings-s4-t1.nff", "rings", 4, 1},   {"tetra-s1.nff", "tetra", 1, 0},
    {"tetra-s9.nff.gz", "tetra", 9, 0},   {"tetra-s10.nff.gz", "tetra", 10, 0},
    {"balls-s1.nff", "balls", 1, 0},      {"balls-s1-t1.nff", "balls", 1, 1},
    {"balls-s4.nff", "balls", 4, 0},
};

// Regenerates `file` and checks it against the reference: the same counts
// per entity kind, the same view, background, lights and materials, and
// every number within the tolerance.
void check_matches_reference(const std::string& file) {
  RAYNODE_REQUIRE_SCENES(dir);
  const auto it = std::find_if(std::begin(kReferences), std::end(kReferences),
                               [&](const Reference& r) { return file == r.file; });
  REQUIRE(it != std::end(kReferences));
  const Scene want = read_nff((dir / "spd" / file).string());
  SpdParams params;
  params.name = it->name;
  params.size = it->size;
  params.tessellate = it->tessellate;
  const Scene got = make_spd_scene(params);
  INFO("reference " << file);
  CHECK(want.dropped_degenerate == 0);
  CHECK(got.counts() == want.counts());
  const SceneDiff diff = compare_scenes(got, want);
  MESSAGE(file << ": " << want.shapes.size() << " shapes, largest scaled deviation "
                << diff.max_deviation);
  INFO(diff.report());
  CHECK(diff.mismatches == 0);
  CHECK(diff.max_deviation <= kTolerance);
}

Scene make(const std::string& name, int size, int tessellate = 0) {
  return make_spd_scene(SpdParams{name, size, tessellate});
}

}  // namespace

TEST_CASE("spd: every non-teapot reference file in MANIFEST.tsv has a comparison test") {
  RAYNODE_REQUIRE_SCENES(dir);
  std::ifstream manifest(dir / "spd" / "MANIFEST.tsv");
  REQUIRE(manifest);
  std::set<std::string> listed;
  std::string line;
  std::getline(manifest, line);  // header
  while (std::getline(manifest, line)) {
    const std::string file = line.substr(0, line.find('\t'));
    if (file.rfind("teapot", 0) == 0 || file.find('/') != std::string::npos) continue;
    listed.insert(file);
  }
  std::set<std::string> tested;
  for (const Reference& r : kReferences) tested.insert(r.file);
  CHECK(listed == tested);
}

TEST_CASE("spd: tetra -s 1 matches tetra-s1.nff") { check_matches_reference("tetra-s1.nff"); }
TEST_CASE("spd: tetra -s 9 matches tetra-s9.nff.gz (paper Tetra9, 262144 triangles)") {
  check_matches_reference("tetra-s9.nff.gz");
}
TEST_CASE("spd: tetra -s 10 matches tetra-s10.nff.gz (paper Tetra10, 1048576 triangles)") {
  check_matches_reference("tetra-s10.nff.gz");
}

TEST_CASE("spd: balls -s 1 matches balls-s1.nff") { check_matches_reference("balls-s1.nff"); }
TEST_CASE("spd: balls -s 1 -t 1 matches balls-s1-t1.nff") {
  check_matches_reference("balls-s1-t1.nff");
}
TEST_CASE("spd: balls -s 4 matches balls-s4.nff (the 7381-sphere sphereflake)") {
  check_matches_reference("balls-s4.nff");
}

TEST_CASE("spd: mount -s 1 matches mount-s1.nff") { check_matches_reference("mount-s1.nff"); }
TEST_CASE("spd: mount -s 1 -t 1 matches mount-s1-t1.nff") {
  check_matches_reference("mount-s1-t1.nff");
}
TEST_CASE("spd: mount -s 6 matches mount-s6.nff (SPD's own RNG and hash)") {
  check_matches_reference("mount-s6.nff");
}
TEST_CASE("spd: mount -s 6 -t 6 matches mount-s6-t6.nff (paper Mountain)") {
  check_matches_reference("mount-s6-t6.nff");
}

TEST_CASE("spd: rings -s 1 matches rings-s1.nff") { check_matches_reference("rings-s1.nff"); }
TEST_CASE("spd: rings -s 1 -t 1 matches rings-s1-t1.nff") {
  check_matches_reference("rings-s1-t1.nff");
}
TEST_CASE("spd: rings -s 3 -t 1 matches rings-s3-t1.nff") {
  check_matches_reference("rings-s3-t1.nff");
}
TEST_CASE("spd: rings -s 4 matches rings-s4.nff") { check_matches_reference("rings-s4.nff"); }
TEST_CASE("spd: rings -s 4 -t 1 matches rings-s4-t1.nff (paper Rings4)") {
  check_matches_reference("rings-s4-t1.nff");
}

TEST_CASE("spd: paper Mountain, mount:6 with -t 6, has 9920 triangles (8192 + 4 x 432)") {
  const SceneCounts c = make("mount", 6, 6).counts();
  CHECK(c.polygons == 8192);
  CHECK(c.patches == 1728);
  CHECK(c.polygons + c.patches == 9920);
  CHECK(c.spheres == 0);
}

TEST_CASE("spd: paper Rings4, rings:4 with -t 1, has 18001 polygons (18000 triangles + backdrop)") {
  const SceneCounts c = make("rings", 4, 1).counts();
  CHECK(c.patches == 18000);
  CHECK(c.polygons == 1);
  CHECK(c.polygons + c.patches == 18001);
  CHECK(c.spheres == 0);
  CHECK(c.cones == 0);
}

TEST_CASE("spd: default sizes are the SPD programs' defaults") {
  CHECK(make("tetra", -1).counts().polygons == 4096);  // tetra -s 6
  CHECK(make("balls", -1).counts().spheres == 7381);   // balls -s 4
  const SceneCounts mount = make("mount", -1).counts();
  CHECK(mount.polygons == 8192);  // mount -s 6
  CHECK(mount.spheres == 4);
  const SceneCounts rings = make("rings", -1).counts();
  CHECK(rings.spheres == 4200);  // rings -s 7: 5*7*8*15
  CHECK(rings.cones == 4200);
}

TEST_CASE("spd: tessellation keeps every shape's place and material, and leaves polygons alone") {
  Scene curved = make("balls", 1);
  Scene flat = curved;
  tessellate_scene(flat, 2);
  REQUIRE(flat.shapes.size() == 1 + 10 * 12 * 4);
  CHECK(flat.shapes[0].kind == ShapeKind::kPolygon);
  CHECK(flat.shapes[0].material == curved.shapes[0].material);
  for (int k = 0; k < 4; ++k) CHECK(flat.vertices[k] == curved.vertices[k]);
  for (std::size_t i = 1; i < flat.shapes.size(); ++i) {
    CHECK(flat.shapes[i].kind == ShapeKind::kPatch);
    CHECK(flat.shapes[i].material == curved.shapes[1 + (i - 1) / 48].material);
  }
  CHECK(flat.materials == curved.materials);
  CHECK(flat.lights == curved.lights);
  CHECK(flat.view == curved.view);
  // Every tessellated vertex lies on its sphere, with the unit normal pointing out.
  for (std::size_t i = 1; i < flat.shapes.size(); ++i) {
    const Sphere& s = curved.spheres[(i - 1) / 48];
    const Shape& t = flat.shapes[i];
    for (std::uint32_t k = 0; k < 3; ++k) {
      const Vec3 p = flat.vertices[t.first + k] - s.center;
      const Vec3 n = flat.normals[t.first_normal + k];
      CHECK(length(p) == doctest::Approx(s.radius).epsilon(1e-5));
      CHECK(length(n) == doctest::Approx(1.0).epsilon(1e-5));
      CHECK(dot(p, n) > 0.0f);
    }
  }
}

TEST_CASE("spd: tessellating a scene without curved primitives changes nothing") {
  Scene tetra = make("tetra", 2);
  const std::size_t shapes = tetra.shapes.size();
  tessellate_scene(tetra, 3);
  CHECK(tetra.shapes.size() == shapes);
  CHECK(tetra.counts() == make("tetra", 2).counts());
}

TEST_CASE("spd: a cylinder along Z tessellates from the X cross direction, 8R triangles") {
  Scene scene;
  scene.materials.push_back(Material{});
  scene.add_cone(Cone{{0, 0, 0}, 1.0f, {0, 0, 2}, 1.0f});
  scene.add_cone(Cone{{0, 0, 0}, 1.0f, {2, 0, 0}, 0.5f});
  tessellate_scene(scene, 3);
  REQUIRE(scene.counts().patches == 2 * 24);
  // axis x (0,0,1) vanishes, so the start direction is axis x (1,0,0) = (0,2,0)/2:
  // the first triangle's second vertex (the first apex point) is (0,1,2).
  const Shape& first = scene.shapes[0];
  CHECK(scene.vertices[first.first + 1].x == doctest::Approx(0.0));
  CHECK(scene.vertices[first.first + 1].y == doctest::Approx(1.0));
  CHECK(scene.vertices[first.first + 1].z == doctest::Approx(2.0));
  // Cone normals tilt towards the apex (base radius 1 > apex radius 0.5).
  for (std::size_t i = 24; i < 48; ++i) {
    const Shape& t = scene.shapes[i];
    for (std::uint32_t k = 0; k < 3; ++k) CHECK(scene.normals[t.first_normal + k].x > 0.0f);
  }
}

TEST_CASE("spd: tessellate_scene rejects a resolution below 1") {
  Scene scene = make("balls", 1);
  CHECK_THROWS_AS(tessellate_scene(scene, 0), std::invalid_argument);
}

TEST_CASE("spd: tessellate_scene refuses a result beyond kMaxTessellatedTriangles, naming the counts, and leaves the scene") {
  Scene scene = make("balls", 1);  // 10 spheres
  const std::size_t shapes = scene.shapes.size();
  // 10 x 12 x 530^2 = 33,708,000 > 2^25; 10 x 12 x 528^2 = 33,454,080 fits.
  CHECK_THROWS_WITH_AS(tessellate_scene(scene, 530),
                       doctest::Contains("10 spheres x 3370800 triangles and 0 cones x 4240 make 33708000 triangles, "
                                         "more than the 33554432 supported"),
                       std::invalid_argument);
  CHECK(scene.shapes.size() == shapes);
  Scene small = make("balls", 1);
  tessellate_scene(small, 2);
  CHECK(small.shapes.size() == shapes - 10 + 10 * 12 * 4);
}

TEST_CASE("spd: tessellate_scene counts a huge resolution without wrapping round 2^64") {
  Scene scene = make("balls", 1);  // 10 spheres and a polygon
  const std::vector<Shape> shapes(scene.shapes.begin(), scene.shapes.end());
  std::size_t spheres = 10;
  for (const Shape& s : shapes)
    if (s.kind == ShapeKind::kSphere && spheres < 16) scene.shapes.push_back(s), ++spheres;
  REQUIRE(scene.counts().spheres == 16);
  // 16 x 12 x (2^30)^2 = 192 x 2^60, which is 0 modulo 2^64.
  CHECK_THROWS_AS(tessellate_scene(scene, 1 << 30), std::invalid_argument);
  CHECK_THROWS_AS(tessellate_scene(scene, 2147483647), std::invalid_argument);
}

TEST_CASE("spd: spd_names lists the eleven generators of SPD 3.14") {
  const std::vector<std::string> names = spd_names();
  CHECK(names == std::vector<std::string>{"teapot", "mount", "rings", "tetra", "balls", "gears",
                                          "tree", "lattice", "shells", "jacks", "sombrero"});
}

TEST_CASE("spd: parse_spd_spec reads name and optional size") {
  const SpdParams tetra = parse_spd_spec("tetra");
  CHECK(tetra.name == "tetra");
  CHECK(tetra.size == -1);
  CHECK(tetra.tessellate == 0);
  const SpdParams mount = parse_spd_spec("mount:3");
  CHECK(mount.name == "mount");
  CHECK(mount.size == 3);
}

TEST_CASE("spd: parse_spd_spec rejects an unknown name and lists the valid ones") {
  try {
    parse_spd_spec("teapott:2");
    FAIL("no exception for an unknown name");
  } catch (const std::invalid_argument& e) {
    const std::string msg = e.what();
    CHECK(msg.find("teapott") != std::string::npos);
    for (const char* name : {"teapot", "mount", "rings", "tetra", "balls"}) {
      CHECK(msg.find(name) != std::string::npos);
    }
  }
  CHECK_THROWS_AS(parse_spd_spec(""), std::invalid_argument);
  CHECK_THROWS_AS(parse_spd_spec("Tetra"), std::invalid_argument);
}

TEST_CASE("spd: parse_spd_spec rejects bad sizes") {
  for (const char* spec : {"tetra:x", "tetra:0", "tetra:-1", "tetra:", "tetra:3x", "tetra:2.5",
                           "tetra: 3", "tetra:99999999999"}) {
    INFO(spec);
    CHECK_THROWS_AS(parse_spd_spec(spec), std::invalid_argument);
  }
}

TEST_CASE("spd: make_spd_scene rejects sizes outside a generator's range") {
  CHECK_THROWS_AS(make("tetra", 0), std::invalid_argument);
  CHECK_THROWS_AS(make("mount", 8), std::invalid_argument);  // SPD's hash shifts by 7 - size
  CHECK_THROWS_AS(make("balls", 0), std::invalid_argument);
  CHECK_THROWS_AS(make("rings", 0), std::invalid_argument);
  CHECK_THROWS_AS(make("unknown", 1), std::invalid_argument);
  CHECK_THROWS_AS(make("balls", 1, -1), std::invalid_argument);
}

TEST_CASE("stadium floor: one square K times the scene's width, under it along the view's up, a material of its own") {
  for (const char* spec : {"teapot:2", "balls:1"}) {
    CAPTURE(spec);
    const Scene plain = load_scene(SceneSource(spec));
    SceneSource with(spec);
    with.floor = 100;
    const Scene s = load_scene(with);
    REQUIRE(s.shapes.size() == plain.shapes.size() + 1);
    CHECK(s.materials.size() == plain.materials.size() + 1);
    const Shape& f = s.shapes.back();
    CHECK(f.kind == ShapeKind::kPolygon);
    CHECK(f.count == 4);
    CHECK(f.material == s.materials.size() - 1);
    // SPD scenes are z-up: the floor lies at one z below the scene, and
    // spans 100x the scene's largest extent on x and y, centred under it.
    const Bounds3 b = plain.bounds();
    const Vec3 e = b.extent();
    const float size = std::max({e.x, e.y, e.z});
    Bounds3 fb;
    for (std::uint32_t i = 0; i < 4; ++i) {
      const Vec3 p = s.vertices[f.first + i];
      fb.extend(p);
      CHECK(p.z == doctest::Approx(b.lower.z - 0.01f * size));
    }
    CHECK(fb.extent().x == doctest::Approx(100 * size));
    CHECK(fb.extent().y == doctest::Approx(100 * size));
    CHECK(fb.center().x == doctest::Approx(b.center().x));
    // Its normal (Newell's, from the vertex order) points up.
    const Vec3 a = s.vertices[f.first], c1 = s.vertices[f.first + 1], c2 = s.vertices[f.first + 2];
    CHECK(cross(c1 - a, c2 - a).z > 0);
  }
  Scene one = load_scene(SceneSource("teapot:2"));
  CHECK_THROWS_AS(add_stadium_floor(one, 0.5), std::invalid_argument);
  CHECK_THROWS_AS(add_stadium_floor(one, 1e7), std::invalid_argument);
  Scene empty;
  CHECK_THROWS_AS(add_stadium_floor(empty, 10), std::invalid_argument);
}
