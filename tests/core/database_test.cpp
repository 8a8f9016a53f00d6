// Tests of the tracing database (database.h) and of the grid's build
// (grid.h): what make_database keeps, splits and records; that build_grid
// lists every primitive in every cell its surface touches, in ascending
// order; and the resolution heuristic.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "core/database.h"
#include "core/direct_view.h"
#include "core/grid.h"
#include "core/math.h"
#include "core/nff.h"
#include "core/scene.h"
#include "core/traverse.h"
#include "scenes_dir.h"

#include "test_random.h"

namespace {

using namespace raynode::core;
using raynode::testing::Rng;
using raynode::testing::random_in_cube;
using raynode::testing::random_unit;
using raynode::testing::uniform;

double triangle_area(const Primitive& p) {
  const Vec3 a = p.vertex(0), b = p.vertex(1), c = p.vertex(2);
  const double u[3] = {double(b.x) - a.x, double(b.y) - a.y, double(b.z) - a.z};
  const double w[3] = {double(c.x) - a.x, double(c.y) - a.y, double(c.z) - a.z};
  const double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
  return 0.5 * std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
}

// Random triangles, spheres and cones in [-1,1]^3.
Scene random_scene(std::uint64_t seed, int triangles, int spheres, int cones, float size) {
  Rng rng(seed);
  Scene s;
  for (int i = 0; i < triangles; ++i) {
    const Vec3 c = random_in_cube(rng, 1);
    const Vec3 v[3] = {c + random_unit(rng) * size, c + random_unit(rng) * size, c + random_unit(rng) * size};
    s.add_polygon(v, 3);
  }
  for (int i = 0; i < spheres; ++i) s.add_sphere({random_in_cube(rng, 1), size * uniform(rng, 0.2f, 1.0f)});
  for (int i = 0; i < cones; ++i) {
    const Vec3 base = random_in_cube(rng, 1);
    s.add_cone({base, size * uniform(rng, 0.1f, 0.6f), base + random_unit(rng) * (2 * size),
                size * uniform(rng, 0.0f, 0.6f)});
  }
  return s;
}

// Points on the primitive's surface (including its edges and end circles).
std::vector<Vec3> surface_samples(const Primitive& p, Rng& rng, int n) {
  std::vector<Vec3> out;
  switch (p.kind) {
    case PrimitiveKind::kTriangle:
      for (int k = 0; k < 3; ++k) out.push_back(p.vertex(k));
      for (int i = 0; i < n; ++i) {
        float a = uniform(rng, 0, 1), b = uniform(rng, 0, 1);
        if (a + b > 1) {
          a = 1 - a;
          b = 1 - b;
        }
        out.push_back(p.vertex(0) + (p.vertex(1) - p.vertex(0)) * a + (p.vertex(2) - p.vertex(0)) * b);
      }
      break;
    case PrimitiveKind::kSphere:
      for (int i = 0; i < n; ++i) out.push_back(p.center() + random_unit(rng) * std::fabs(p.radius()));
      break;
    case PrimitiveKind::kCone: {
      const Vec3 axis = p.cone_apex() - p.cone_base();
      const Vec3 w = normalize(axis);
      const Vec3 u = normalize(cross(w, std::fabs(w.x) < 0.6f ? Vec3{1, 0, 0} : Vec3{0, 1, 0}));
      const Vec3 v = cross(w, u);
      for (int i = 0; i < n; ++i) {
        const float s = (i < 4) ? float(i % 2) : uniform(rng, 0, 1);
        const float ang = uniform(rng, 0, 6.2831853f);
        const float r = std::fabs(p.cone_base_radius()) * (1 - s) + std::fabs(p.cone_apex_radius()) * s;
        out.push_back(p.cone_base() + axis * s + (u * std::cos(ang) + v * std::sin(ang)) * r);
      }
      break;
    }
  }
  return out;
}

// Checks the CSR invariants and that every sampled surface point's cell
// lists the primitive. Returns the number of points checked.
std::size_t check_grid_membership(const Database& db, const Grid& g, std::uint64_t seed, int samples) {
  const GridInfo& info = g.info;
  REQUIRE(g.cell_start.size() == std::size_t(info.cell_count()) + 1);
  CHECK(g.cell_start.front() == 0);
  CHECK(g.cell_start.back() == g.cell_primitives.size());
  std::size_t unsorted = 0, out_of_range = 0, offsets_decreasing = 0;
  std::vector<bool> listed(db.primitives.size(), false);
  for (std::uint32_t c = 0; c < info.cell_count(); ++c) {
    offsets_decreasing += g.cell_start[c] > g.cell_start[c + 1];
    for (std::uint32_t i = g.cell_start[c]; i < g.cell_start[c + 1]; ++i) {
      const std::uint32_t id = g.cell_primitives[i];
      if (id >= db.primitives.size()) {
        ++out_of_range;
        continue;
      }
      listed[id] = true;
      if (i > g.cell_start[c] && !(g.cell_primitives[i - 1] < id)) ++unsorted;  // strictly: no duplicates
    }
  }
  CHECK(offsets_decreasing == 0);
  CHECK(out_of_range == 0);
  CHECK(unsorted == 0);
  CHECK(std::count(listed.begin(), listed.end(), false) == 0);

  Rng rng(seed);
  std::size_t points = 0, missing = 0;
  std::string first;
  for (std::uint32_t id = 0; id < db.primitives.size(); ++id) {
    for (const Vec3& q : surface_samples(db.primitives[id], rng, samples)) {
      int cell[3];
      for (int a = 0; a < 3; ++a) {
        const int c = int(std::floor((q[a] - info.bounds.lower[a]) * info.inv_cell_size[a]));
        cell[a] = std::clamp(c, 0, info.res[a] - 1);
      }
      const std::uint32_t ci = info.cell_index(cell[0], cell[1], cell[2]);
      const auto b = g.cell_primitives.begin() + g.cell_start[ci], e = g.cell_primitives.begin() + g.cell_start[ci + 1];
      ++points;
      if (!std::binary_search(b, e, id)) {
        if (missing++ == 0)
          first = "primitive " + std::to_string(id) + " not listed in cell (" + std::to_string(cell[0]) + "," +
                  std::to_string(cell[1]) + "," + std::to_string(cell[2]) + ") holding one of its points";
      }
    }
  }
  INFO(first);
  CHECK(missing == 0);
  return points;
}

}  // namespace

// ---------------------------------------------------------------------------
// make_database

TEST_CASE("database: a quad becomes two triangles that cover it, facing like it, with the quad's shape index") {
  Scene s;
  const Vec3 quad[4] = {{0, 0, 0}, {2, 0, 0}, {2, 1, 0}, {0, 1, 0}};  // counter-clockwise seen from +z
  s.add_polygon(quad, 4);
  const Database db = make_database(s);
  REQUIRE(db.primitives.size() == 2);
  CHECK(db.counts().triangles == 2);
  CHECK(db.shape_count == 1);
  double area = 0;
  std::set<std::pair<float, float>> used;
  for (const Primitive& p : db.primitives) {
    CHECK(p.kind == PrimitiveKind::kTriangle);
    CHECK(p.shape == 0);
    CHECK(p.material == 0);
    CHECK(p.normals == kNoNormals);
    CHECK(cross(p.vertex(1) - p.vertex(0), p.vertex(2) - p.vertex(0)).z > 0.0f);
    area += triangle_area(p);
    for (int k = 0; k < 3; ++k) {
      CHECK(std::count(std::begin(quad), std::end(quad), p.vertex(k)) == 1);  // only the quad's own corners
      used.insert({p.vertex(k).x, p.vertex(k).y});
    }
  }
  CHECK(area == doctest::Approx(2.0).epsilon(1e-12));
  CHECK(used.size() == 4);
  CHECK(db.dropped_degenerate_triangles == 0);
}

TEST_CASE("database: a pp patch keeps each vertex normal with its own vertex") {
  // A quad patch and a concave L-shaped patch (ear clipping reorders
  // corners), each vertex with a distinct normal.
  const Vec3 quad[4] = {{0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  const Vec3 l_shape[6] = {{0, 0, 2}, {2, 0, 2}, {2, 0.5f, 2}, {0.5f, 0.5f, 2}, {0.5f, 2, 2}, {0, 2, 2}};
  std::vector<Vec3> normals;
  for (int i = 0; i < 10; ++i) normals.push_back(normalize(Vec3{0.1f * float(i), -0.05f * float(i), 1}));
  Scene s;
  s.add_patch(quad, normals.data(), 4);
  const Vec3 plain[3] = {{5, 5, 5}, {6, 5, 5}, {5, 6, 5}};
  s.add_polygon(plain, 3);
  s.add_patch(l_shape, normals.data() + 4, 6);
  const Database db = make_database(s);
  REQUIRE(db.primitives.size() == 2 + 1 + 4);
  CHECK(db.counts().vertex_normal_sets == 6);
  CHECK(db.vertex_normals.size() == 6);
  std::size_t checked = 0;
  std::set<std::uint32_t> normal_sets;
  for (const Primitive& p : db.primitives) {
    if (p.shape == 1) {
      CHECK(p.normals == kNoNormals);  // plain polygon: no vertex normals
      continue;
    }
    REQUIRE(p.normals != kNoNormals);
    REQUIRE(p.normals < db.vertex_normals.size());
    CHECK(normal_sets.insert(p.normals).second);  // each triangle its own record
    const Vec3* verts = p.shape == 0 ? quad : l_shape;
    const int n = p.shape == 0 ? 4 : 6;
    const Vec3* vn = p.shape == 0 ? normals.data() : normals.data() + 4;
    for (int k = 0; k < 3; ++k) {
      const int j = int(std::find(verts, verts + n, p.vertex(k)) - verts);
      REQUIRE(j < n);
      CHECK(db.vertex_normals[p.normals].n[k] == vn[j]);
      ++checked;
    }
  }
  CHECK(checked == 18);
}

TEST_CASE("database: spheres and cones stay analytic with their parameters and materials") {
  Scene s;
  s.materials.push_back(Material{{1, 0, 0}, 0.5f, 0.5f, 10, 0, 1});
  s.add_sphere({{1, 2, 3}, 0.5f});
  s.materials.push_back(Material{{0, 1, 0}, 0.7f, 0.1f, 3, 0.2f, 1.5f});
  s.add_cone({{0, 0, 0}, 1.0f, {0, 0, 4}, 0.25f});
  s.add_sphere({{-1, -2, -3}, 2.0f});
  const Database db = make_database(s);
  REQUIRE(db.primitives.size() == 3);
  const DatabaseCounts c = db.counts();
  CHECK(c.spheres == 2);
  CHECK(c.cones == 1);
  CHECK(c.triangles == 0);
  const Primitive& s0 = db.primitives[0];
  CHECK(s0.kind == PrimitiveKind::kSphere);
  CHECK(s0.center() == Vec3{1, 2, 3});
  CHECK(s0.radius() == 0.5f);
  CHECK(s0.material == 0);
  const Primitive& c1 = db.primitives[1];
  CHECK(c1.kind == PrimitiveKind::kCone);
  CHECK(c1.cone_base() == Vec3{0, 0, 0});
  CHECK(c1.cone_base_radius() == 1.0f);
  CHECK(c1.cone_apex() == Vec3{0, 0, 4});
  CHECK(c1.cone_apex_radius() == 0.25f);
  CHECK(c1.material == 1);
  CHECK(db.primitives[2].material == 1);
  CHECK(db.primitives[2].radius() == 2.0f);
  REQUIRE(db.materials.size() == 2);
  CHECK(db.materials[1] == s.materials[1]);
  CHECK(db.bytes() == 3 * sizeof(Primitive) + 2 * sizeof(Material));
}

TEST_CASE("database: the shape index is the file order across polygons, patches, spheres and cones") {
  Scene s;
  const Vec3 pent[5] = {{0, 0, 0}, {1, 0, 0}, {1.3f, 0.8f, 0}, {0.5f, 1.4f, 0}, {-0.3f, 0.8f, 0}};
  const Vec3 quad[4] = {{0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  const Vec3 qn[4] = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {0, 0, 1}};
  s.add_polygon(quad, 4);      // shape 0: 2 triangles
  s.add_sphere({{3, 0, 0}, 1});  // shape 1
  s.add_polygon(pent, 5);      // shape 2: 3 triangles
  s.add_cone({{5, 0, 0}, 1, {5, 0, 2}, 1});  // shape 3
  s.add_patch(quad, qn, 4);    // shape 4: 2 triangles
  const Database db = make_database(s);
  std::vector<std::uint32_t> shapes;
  for (const Primitive& p : db.primitives) shapes.push_back(p.shape);
  CHECK(shapes == std::vector<std::uint32_t>{0, 0, 1, 2, 2, 2, 3, 4, 4});
  CHECK(db.shape_count == 5);
  // The pentagon keeps its area.
  double area = 0;
  for (const Primitive& p : db.primitives)
    if (p.shape == 2) area += triangle_area(p);
  double shoelace = 0;
  for (int i = 0; i < 5; ++i) shoelace += double(pent[i].x) * pent[(i + 1) % 5].y - double(pent[(i + 1) % 5].x) * pent[i].y;
  CHECK(area == doctest::Approx(0.5 * shoelace).epsilon(1e-7));
}

TEST_CASE("database: bounds enclose every primitive exactly, spheres and cones by their radii") {
  Scene s;
  const Vec3 tri[3] = {{-1, 0, 0}, {2, 1, 0}, {0, 3, -1}};
  s.add_polygon(tri, 3);
  s.add_sphere({{5, 5, 5}, 1.5f});
  s.add_sphere({{0, -4, 0}, -0.5f});  // negative radius: its magnitude
  s.add_cone({{0, 0, 10}, 2.0f, {0, 0, 12}, 0.5f});
  const Database db = make_database(s);
  CHECK(db.bounds.lower == Vec3{-2, -4.5f, -1});
  CHECK(db.bounds.upper == Vec3{6.5f, 6.5f, 12.5f});
  Bounds3 b;
  for (const Primitive& p : db.primitives) b.extend(p.bounds());
  CHECK(b.lower == db.bounds.lower);
  CHECK(b.upper == db.bounds.upper);
  CHECK(db.primitives[2].bounds().lower == Vec3{-0.5f, -4.5f, -0.5f});
  // A scene's own bounds agree with the database's.
  CHECK(s.bounds().lower == db.bounds.lower);
  CHECK(s.bounds().upper == db.bounds.upper);
  // An empty scene: an empty box.
  CHECK(make_database(Scene{}).bounds.empty());
}

TEST_CASE("database: view, lights, background and materials are carried over from the scene") {
  Scene s;
  s.has_view = true;
  s.view.from = {1, 2, 3};
  s.view.angle = 30;
  s.view.width = 64;
  s.background = {0.1f, 0.2f, 0.3f};
  s.lights.push_back(Light{{4, 5, 6}, {1, 1, 1}, false});
  const Database db = make_database(s);
  CHECK(db.has_view);
  CHECK(db.view == s.view);
  CHECK(db.background == s.background);
  REQUIRE(db.lights.size() == 1);
  CHECK(db.lights[0] == s.lights[0]);
  // A scene without materials still gets one (primitives index it).
  CHECK(db.materials.size() == 1);
  CHECK(db.primitives.empty());
}

TEST_CASE("database: every SPD reference scene splits into n-2 triangles per polygon, in file order") {
  RAYNODE_REQUIRE_SCENES(dir);
  namespace fs = std::filesystem;
  std::size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir / "spd")) {
    if (e.path().extension() != ".nff" || fs::file_size(e.path()) > 3'000'000) continue;
    CAPTURE(e.path().filename().string());
    ++files;
    const Scene s = read_nff(e.path().string());
    const Database db = make_database(s);
    std::size_t expected = 0;
    for (const Shape& sh : s.shapes)
      expected += (sh.kind == ShapeKind::kPolygon || sh.kind == ShapeKind::kPatch) ? sh.count - 2 : 1;
    CHECK(db.primitives.size() + db.dropped_degenerate_triangles == expected);
    CHECK(db.shape_count == s.shapes.size());
    std::size_t out_of_order = 0, kind_mismatch = 0;
    std::vector<bool> seen(s.shapes.size(), false);
    for (std::size_t i = 0; i < db.primitives.size(); ++i) {
      const Primitive& p = db.primitives[i];
      REQUIRE(p.shape < s.shapes.size());
      seen[p.shape] = true;
      out_of_order += i > 0 && p.shape < db.primitives[i - 1].shape;
      const ShapeKind k = s.shapes[p.shape].kind;
      const PrimitiveKind want = k == ShapeKind::kSphere ? PrimitiveKind::kSphere
                                 : k == ShapeKind::kCone ? PrimitiveKind::kCone
                                                         : PrimitiveKind::kTriangle;
      kind_mismatch += p.kind != want;
      kind_mismatch += (k == ShapeKind::kPatch) != (p.normals != kNoNormals);
      CHECK(p.material == s.shapes[p.shape].material);
    }
    CHECK(out_of_order == 0);
    CHECK(kind_mismatch == 0);
    // A shape without primitives can only be a polygon whose every piece
    // was dropped as zero-area.
    std::size_t unseen = 0, unseen_curved = 0;
    for (std::size_t i = 0; i < seen.size(); ++i) {
      unseen += !seen[i];
      unseen_curved += !seen[i] && (s.shapes[i].kind == ShapeKind::kSphere || s.shapes[i].kind == ShapeKind::kCone);
    }
    CHECK(unseen_curved == 0);
    CHECK(unseen <= db.dropped_degenerate_triangles);
  }
  CHECK(files >= 10);
}

// ---------------------------------------------------------------------------
// build_grid

TEST_CASE("grid build: every primitive is listed in every cell its surface passes through, lists ascending") {
  const Scene s = random_scene(1, 300, 40, 30, 0.25f);
  const Database db = make_database(s);
  for (const float density : {0.5f, 2.0f, 8.0f}) {
    CAPTURE(density);
    GridParams gp;
    gp.density = density;
    const Grid g = build_grid(db, gp);
    CHECK(check_grid_membership(db, g, 2, 60) > 20000);
  }
  // Forced resolutions, including 1 cell and very thin cells.
  for (const auto& r : {std::array<int, 3>{1, 1, 1}, std::array<int, 3>{17, 3, 40}, std::array<int, 3>{64, 64, 64}}) {
    GridParams gp;
    gp.resolution[0] = r[0];
    gp.resolution[1] = r[1];
    gp.resolution[2] = r[2];
    const Grid g = build_grid(db, gp);
    CHECK(g.info.res[0] == r[0]);
    CHECK(g.info.res[1] == r[1]);
    CHECK(g.info.res[2] == r[2]);
    check_grid_membership(db, g, 3, 30);
  }
}

TEST_CASE("grid build: a triangle is listed in exactly the cells it meets, flat, thin or slanted") {
  // Triangles of about one to three cells, a third of them flat on one axis
  // (most within one cell's slab) and a third on two (most a row of cells):
  // each is listed in a cell if and only if it meets the cell's box, up to
  // the builder's inflation of the boxes (1e-4 of a cell); checked against
  // the separating-axis test on every cell of its box and the two around it.
  Rng rng(11);
  Scene s;
  const int res = 16;
  const float cell = 2.0f / float(res);
  for (int i = 0; i < 600; ++i) {
    const int flat_axes = i % 3;
    const Vec3 c = random_in_cube(rng, 0.8f);
    Vec3 v[3];
    for (Vec3& p : v) p = c + random_unit(rng) * (cell * uniform(rng, 0.3f, 1.5f));
    for (int k = 0; k < flat_axes; ++k) {
      const int a = (i / 3 + k) % 3;
      for (Vec3& p : v) {  // within 1/20 of a cell on axis a: mostly one cell's slab
        float& x = a == 0 ? p.x : (a == 1 ? p.y : p.z);
        x = c[a] + cell * uniform(rng, 0.0f, 0.05f);
      }
    }
    s.add_polygon(v, 3);
  }
  const Database db = make_database(s);
  GridParams gp;
  gp.kind = GridKind::kUniform;
  gp.resolution[0] = gp.resolution[1] = gp.resolution[2] = res;
  const Grid g = build_grid(db, gp);
  const GridInfo& info = g.info;
  std::vector<std::set<std::uint32_t>> lists(db.primitives.size());
  for (std::uint32_t c = 0; c < info.cell_count(); ++c)
    for (std::uint32_t k = g.cell_start[c]; k < g.cell_start[c + 1]; ++k) lists[g.cell_primitives[k]].insert(c);
  std::size_t missing = 0, spurious = 0, listed = 0, multi_cell = 0;
  for (std::uint32_t pi = 0; pi < db.primitives.size(); ++pi) {
    const Primitive& p = db.primitives[pi];
    if (p.kind != PrimitiveKind::kTriangle) continue;
    multi_cell += lists[pi].size() > 1;
    const Bounds3 pb = p.bounds();
    int lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::max(0, int(std::floor((pb.lower[a] - info.bounds.lower[a]) / info.cell_size[a])) - 1);
      hi[a] = std::min(info.res[a] - 1, int(std::floor((pb.upper[a] - info.bounds.lower[a]) / info.cell_size[a])) + 1);
    }
    for (int z = lo[2]; z <= hi[2]; ++z)
      for (int y = lo[1]; y <= hi[1]; ++y)
        for (int x = lo[0]; x <= hi[0]; ++x) {
          const Bounds3 box = info.cell_bounds(x, y, z);
          const Vec3 grow = info.cell_size * 2e-4f;
          const bool in_list = lists[pi].count(info.cell_index(x, y, z)) > 0;
          listed += in_list;
          missing += !in_list && triangle_overlaps_box(p.vertex(0), p.vertex(1), p.vertex(2), box);
          spurious += in_list && !triangle_overlaps_box(p.vertex(0), p.vertex(1), p.vertex(2),
                                                        Bounds3{box.lower - grow, box.upper + grow});
        }
  }
  CHECK(missing == 0);
  CHECK(spurious == 0);
  CHECK(multi_cell > 200);  // the row, plane and general tests all ran
  CHECK(listed > 1000);
}

TEST_CASE("grid build: SPD reference scenes list every primitive in every cell it touches") {
  RAYNODE_REQUIRE_SCENES(dir);
  for (const char* name : {"teapot-s2.nff", "rings-s1.nff", "balls-s1-t1.nff", "mount-s1-t1.nff", "tetra-s1.nff"}) {
    CAPTURE(name);
    const Database db = make_database(read_nff((dir / "spd" / name).string()));
    const Grid g = build_grid(db);
    check_grid_membership(db, g, 4, 40);
  }
}

TEST_CASE("grid build: the grid box contains the database box and its cells tile it") {
  const Scene s = random_scene(5, 100, 10, 5, 0.2f);
  const Database db = make_database(s);
  const Grid g = build_grid(db);
  const GridInfo& info = g.info;
  for (int a = 0; a < 3; ++a) {
    CHECK(info.bounds.lower[a] < db.bounds.lower[a]);  // padded
    CHECK(info.bounds.upper[a] > db.bounds.upper[a]);
    CHECK(info.cell_size[a] * float(info.res[a]) == doctest::Approx(info.bounds.extent()[a]).epsilon(1e-6));
    CHECK(info.inv_cell_size[a] == doctest::Approx(1.0f / info.cell_size[a]));
  }
  const int last[3] = {info.res[0] - 1, info.res[1] - 1, info.res[2] - 1};
  CHECK(info.cell_bounds(0, 0, 0).lower == info.bounds.lower);
  CHECK(info.cell_bounds(last[0], last[1], last[2]).upper == info.bounds.upper);
  // Neighbouring cells share their faces.
  CHECK(info.cell_bounds(0, 0, 0).upper.x == info.cell_bounds(1, 0, 0).lower.x);
  CHECK(info.cell_index(last[0], last[1], last[2]) == info.cell_count() - 1);
  CHECK(info.cell_index(1, 0, 0) == 1);
  CHECK(info.cell_index(0, 1, 0) == std::uint32_t(info.res[0]));
}

TEST_CASE("grid build: building twice gives identical lists") {
  const Database db = make_database(random_scene(6, 200, 20, 10, 0.3f));
  const Grid a = build_grid(db), b = build_grid(db);
  CHECK(a.cell_start == b.cell_start);
  CHECK(a.cell_primitives == b.cell_primitives);
  CHECK(a.references() == a.cell_primitives.size());
  CHECK(a.empty_distance == b.empty_distance);
  CHECK(a.bytes() == (a.cell_start.size() + a.cell_primitives.size()) * sizeof(std::uint32_t) + a.cell_start.size() - 1);
  std::size_t empty = 0;
  for (std::uint32_t c = 0; c < a.info.cell_count(); ++c) empty += a.cell_start[c] == a.cell_start[c + 1];
  CHECK(a.empty_cells() == empty);
}

TEST_CASE("grid build: an empty scene gives a 1x1x1 grid with no references, through which rays miss") {
  const Database db = make_database(Scene{});
  const Grid g = build_grid(db);
  CHECK(g.info.res[0] == 1);
  CHECK(g.info.res[1] == 1);
  CHECK(g.info.res[2] == 1);
  CHECK(g.info.cell_count() == 1);
  CHECK(g.cell_start == std::vector<std::uint32_t>{0, 0});
  CHECK(g.references() == 0);
  CHECK(g.empty_cells() == 1);
  CHECK_FALSE(g.info.bounds.empty());
  const DirectView view(db, g);
  TraversalScratch scratch;
  Hit h;
  for (const Ray& r : {Ray{{-5, 0, 0}, {1, 0, 0}, 0, kInfinity}, Ray{{0, 0, 0}, {0, 1, 1}, 0, kInfinity}}) {
    CHECK_FALSE(intersect_closest(view, r, h, scratch));
    CHECK_FALSE(h.found());
    CHECK_FALSE(intersect_any(view, r, scratch));
  }
}

TEST_CASE("grid build: choose_grid_resolution makes about density x N cells of near-equal edge") {
  const struct {
    Bounds3 box;
    std::size_t n;
    float density;
  } cases[] = {
      {{{0, 0, 0}, {1, 1, 1}}, 1000, 2.0f},   {{{0, 0, 0}, {4, 2, 1}}, 1000, 2.0f},
      {{{-5, -5, -5}, {5, 5, 5}}, 50000, 2.0f}, {{{0, 0, 0}, {1, 3, 9}}, 20000, 0.5f},
      {{{0, 0, 0}, {1, 1, 1}}, 4096, 8.0f},    {{{10, 20, 30}, {13, 21, 31}}, 3000, 1.0f},
  };
  for (const auto& c : cases) {
    CAPTURE(c.n);
    CAPTURE(c.density);
    GridParams gp;
    gp.density = c.density;
    int res[3];
    choose_grid_resolution(c.box, c.n, gp, res);
    const double cells = double(res[0]) * res[1] * res[2];
    const double target = double(c.density) * double(c.n);
    CHECK(cells >= 0.75 * target);
    CHECK(cells <= 1.33 * target);
    // Cells are near-cubes: the edge lengths agree within the rounding of
    // one cell per axis.
    const Vec3 e = c.box.extent();
    for (int a = 0; a < 3; ++a) {
      CHECK(res[a] >= 1);
      const double edge = e[a] / res[a], ideal = std::cbrt(double(e.x) * e.y * e.z / target);
      CHECK(edge == doctest::Approx(ideal).epsilon(0.5 / res[a] + 0.02));
    }
  }
}

TEST_CASE("grid build: flat scenes get one cell on each flat axis") {
  GridParams gp;
  int res[3];
  // A plane: z flat.
  choose_grid_resolution({{0, 0, 5}, {4, 2, 5}}, 1000, gp, res);
  CHECK(res[2] == 1);
  CHECK(double(res[0]) * res[1] == doctest::Approx(2000).epsilon(0.1));
  CHECK(res[0] == doctest::Approx(2 * res[1]).epsilon(0.1));
  // Flat below 1e-3 of the largest extent counts as flat.
  choose_grid_resolution({{0, 0, 0}, {4, 1e-4f, 4}}, 500, gp, res);
  CHECK(res[1] == 1);
  CHECK(double(res[0]) * res[2] == doctest::Approx(1000).epsilon(0.1));
  // A line: two flat axes.
  choose_grid_resolution({{0, 0, 0}, {0, 0, 10}}, 100, gp, res);
  CHECK(res[0] == 1);
  CHECK(res[1] == 1);
  CHECK(res[2] == 200);
  // Through build_grid: quads in the plane y = 1.
  Scene s;
  for (int i = 0; i < 50; ++i) {
    const float x = float(i % 10), z = float(i / 10);
    const Vec3 q[4] = {{x, 1, z}, {x + 0.5f, 1, z}, {x + 0.5f, 1, z + 0.5f}, {x, 1, z + 0.5f}};
    s.add_polygon(q, 4);
  }
  const Database db = make_database(s);
  const Grid g = build_grid(db);
  CHECK(g.info.res[1] == 1);
  CHECK(g.info.res[0] > 1);
  CHECK(g.info.res[2] > 1);
  check_grid_membership(db, g, 7, 20);
}

TEST_CASE("grid build: max_resolution caps every axis and a forced resolution is used as given") {
  GridParams gp;
  gp.max_resolution = 16;
  int res[3];
  choose_grid_resolution({{0, 0, 0}, {100, 1, 1}}, 100000, gp, res);
  CHECK(res[0] == 16);
  CHECK(res[1] <= 16);
  CHECK(res[2] <= 16);
  GridParams forced;
  forced.resolution[0] = 3;
  forced.resolution[1] = 5;
  forced.resolution[2] = 7;
  choose_grid_resolution({{0, 0, 0}, {1, 1, 1}}, 100000, forced, res);
  CHECK(res[0] == 3);
  CHECK(res[1] == 5);
  CHECK(res[2] == 7);
  forced.max_resolution = 4;
  choose_grid_resolution({{0, 0, 0}, {1, 1, 1}}, 10, forced, res);
  CHECK(res[0] == 3);
  CHECK(res[1] == 4);
  CHECK(res[2] == 4);
}

TEST_CASE("grid build: triangle_overlaps_box finds overlap even with no vertex inside, and every separating axis") {
  const Bounds3 box{{0, 0, 0}, {1, 1, 1}};
  // A vertex inside.
  CHECK(triangle_overlaps_box({0.5f, 0.5f, 0.5f}, {3, 0, 0}, {0, 3, 0}, box));
  // A large triangle slicing through the box, every vertex outside.
  CHECK(triangle_overlaps_box({-10, -10, 0.5f}, {10, -10, 0.5f}, {0, 10, 0.5f}, box));
  // Touching a face (inclusive).
  CHECK(triangle_overlaps_box({-1, -1, 1}, {3, -1, 1}, {0, 3, 1}, box));
  // Separated by a box face axis.
  CHECK_FALSE(triangle_overlaps_box({-1, -1, 1.001f}, {3, -1, 1.001f}, {0, 3, 1.001f}, box));
  // Separated by the triangle's plane: plane x + y + z = 3.1 misses the box
  // (max 3) though its bounding box overlaps.
  CHECK_FALSE(triangle_overlaps_box({3.1f, 0, 0}, {0, 3.1f, 0}, {0, 0, 3.1f}, box));
  CHECK(triangle_overlaps_box({2.9f, 0, 0}, {0, 2.9f, 0}, {0, 0, 2.9f}, box));
  // Separated only by an edge x axis product: in the plane z = 0.5 (which
  // cuts the box), its box overlapping, but beyond the line x + y = 2.
  CHECK_FALSE(triangle_overlaps_box({1.5f, 0.6f, 0.5f}, {0.6f, 1.5f, 0.5f}, {1.5f, 1.5f, 0.5f}, box));
  CHECK(triangle_overlaps_box({1.4f, 0.5f, 0.5f}, {0.5f, 1.4f, 0.5f}, {1.5f, 1.5f, 0.5f}, box));
  // Degenerate (a segment) crossing the box still overlaps; beside it does not.
  CHECK(triangle_overlaps_box({-1, 0.5f, 0.5f}, {2, 0.5f, 0.5f}, {0.5f, 0.5f, 0.5f}, box));
  CHECK_FALSE(triangle_overlaps_box({-1, 1.5f, 0.5f}, {2, 1.5f, 0.5f}, {0.5f, 1.5f, 0.5f}, box));
}
