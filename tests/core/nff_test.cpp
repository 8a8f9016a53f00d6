// Tests for the NFF reader and writer (core/nff.h): the SPD reference files
// under ../shared/scenes/spd, round trips, and the error locations of
// malformed input.
#include "core/nff.h"

#include <doctest/doctest.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include <unistd.h>

#include "scenes_dir.h"

namespace fs = std::filesystem;
using raynode::core::Cone;
using raynode::core::Light;
using raynode::core::Material;
using raynode::core::ParseError;
using raynode::core::parse_nff;
using raynode::core::read_nff;
using raynode::core::Scene;
using raynode::core::Shape;
using raynode::core::ShapeKind;
using raynode::core::Sphere;
using raynode::core::Vec3;
using raynode::core::write_nff;
using raynode::core::write_nff_file;

namespace {

/// Index of the first element where a and b differ, or -1 (sizes must match).
template <class T, class Eq>
long first_mismatch(const std::vector<T>& a, const std::vector<T>& b, Eq eq) {
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (!eq(a[i], b[i])) return static_cast<long>(i);
  }
  return -1;
}

template <class T>
long first_mismatch(const std::vector<T>& a, const std::vector<T>& b) {
  return first_mismatch(a, b, [](const T& x, const T& y) { return x == y; });
}

bool same_shape(const Shape& a, const Shape& b) {
  return a.kind == b.kind && a.material == b.material && a.first == b.first &&
         a.count == b.count && (a.kind != ShapeKind::kPatch || a.first_normal == b.first_normal);
}

/// Field-by-field scene equality (one assertion per field, not per element).
void check_same_scene(const Scene& a, const Scene& b) {
  CHECK(a.counts() == b.counts());
  CHECK(a.has_view == b.has_view);
  CHECK(a.view == b.view);
  CHECK(a.background == b.background);
  REQUIRE(a.lights.size() == b.lights.size());
  CHECK(first_mismatch(a.lights, b.lights) == -1);
  REQUIRE(a.materials.size() == b.materials.size());
  CHECK(first_mismatch(a.materials, b.materials) == -1);
  REQUIRE(a.shapes.size() == b.shapes.size());
  CHECK(first_mismatch(a.shapes, b.shapes, same_shape) == -1);
  REQUIRE(a.vertices.size() == b.vertices.size());
  CHECK(first_mismatch(a.vertices, b.vertices) == -1);
  REQUIRE(a.normals.size() == b.normals.size());
  CHECK(first_mismatch(a.normals, b.normals) == -1);
  REQUIRE(a.spheres.size() == b.spheres.size());
  CHECK(first_mismatch(a.spheres, b.spheres) == -1);
  REQUIRE(a.cones.size() == b.cones.size());
  CHECK(first_mismatch(a.cones, b.cones) == -1);
  CHECK(a.dropped_degenerate == b.dropped_degenerate);
}

std::string to_nff(const Scene& s) {
  std::ostringstream out;
  write_nff(out, s);
  return out.str();
}

/// The ParseError that parsing `text` throws, or nothing.
std::optional<ParseError> parse_error(std::string_view text, const std::string& name = "t.nff") {
  try {
    parse_nff(text, name);
  } catch (const ParseError& e) {
    return e;
  }
  return std::nullopt;
}

/// Checks that `text` fails at line:col with exactly `message`.
void check_error(std::string_view text, int line, int col, const std::string& message) {
  CAPTURE(text);
  const std::optional<ParseError> e = parse_error(text);
  REQUIRE(e.has_value());
  CHECK(e->line() == line);
  CHECK(e->column() == col);
  CHECK(e->message() == message);
}

/// A fresh, empty temporary directory, removed when the object dies.
struct TempDir {
  fs::path path;
  TempDir() {
    static std::atomic<int> counter{0};
    path = fs::temp_directory_path() /
           ("raynode-nff-test-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

struct ManifestRow {
  std::string file;
  std::size_t polygons, patches, spheres, cones, lights, materials;
};

/// The rows of spd/MANIFEST.tsv that name a scene file in spd/.
std::vector<ManifestRow> read_manifest(const fs::path& spd) {
  std::ifstream in(spd / "MANIFEST.tsv");
  std::vector<ManifestRow> rows;
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::vector<std::string> cols;
    std::size_t start = 0;
    for (;;) {
      const std::size_t tab = line.find('\t', start);
      cols.push_back(line.substr(start, tab - start));
      if (tab == std::string::npos) break;
      start = tab + 1;
    }
    if (cols.size() < 9 || cols[0].find('/') != std::string::npos) continue;
    rows.push_back({cols[0], std::stoul(cols[3]), std::stoul(cols[4]), std::stoul(cols[5]),
                    std::stoul(cols[6]), std::stoul(cols[7]), std::stoul(cols[8])});
  }
  return rows;
}

const char* const kViewBlock =
    "v\nfrom 0 0 0\nat 0 0 -1\nup 0 1 0\nangle 45\nhither 1\n";

}  // namespace

// ---------------------------------------------------------------------------
// Reference files
// ---------------------------------------------------------------------------

TEST_CASE("nff: every SPD reference file parses with exactly the manifest's counts") {
  RAYNODE_REQUIRE_SCENES(dir);
  const std::vector<ManifestRow> rows = read_manifest(dir / "spd");
  REQUIRE(rows.size() == 18);
  for (const ManifestRow& row : rows) {
    CAPTURE(row.file);
    const Scene s = read_nff((dir / "spd" / row.file).string());
    const auto c = s.counts();
    CHECK(c.polygons == row.polygons);
    CHECK(c.patches == row.patches);
    CHECK(c.spheres == row.spheres);
    CHECK(c.cones == row.cones);
    CHECK(c.lights == row.lights);
    CHECK(c.materials == row.materials);
    CHECK(c.dropped_degenerate == 0);
    CHECK(s.has_view);
  }
}

TEST_CASE("nff: tetra-s10.nff.gz reads as 1048576 triangles") {
  RAYNODE_REQUIRE_SCENES(dir);
  const Scene s = read_nff((dir / "spd" / "tetra-s10.nff.gz").string());
  const auto c = s.counts();
  CHECK(c.polygons == 1048576);
  CHECK(c.patches + c.spheres + c.cones == 0);
  CHECK(s.vertices.size() == 3 * 1048576);
  CHECK(s.materials.size() == 1);
  CHECK(s.view.width == 512);
}

TEST_CASE("nff: reference file values land in the right fields") {
  RAYNODE_REQUIRE_SCENES(dir);
  // tetra-s1.nff: b 0.078 0.361 0.753; up -0.816497 ...; l 2 -18 -5;
  // f 1 0.2 0.2 1 0 100000 0 0; first p 3 starts at -1 -1 1.
  const Scene s = read_nff((dir / "spd" / "tetra-s1.nff").string());
  CHECK(s.background == Vec3{0.078f, 0.361f, 0.753f});
  CHECK(s.view.up == Vec3{-0.816497f, -0.816497f, 0.816497f});
  CHECK(s.view.hither == 1.0f);
  CHECK(s.view.angle == 45.0f);
  REQUIRE(s.lights.size() == 1);
  CHECK(s.lights[0].position == Vec3{2, -18, -5});
  CHECK_FALSE(s.lights[0].has_color);
  REQUIRE(s.materials.size() == 1);
  CHECK(s.materials[0] == Material{{1, 0.2f, 0.2f}, 1, 0, 100000, 0, 0});
  REQUIRE(s.shapes.size() == 4);
  CHECK(s.shapes[0].count == 3);
  CHECK(s.vertices[0] == Vec3{-1, -1, 1});
}

TEST_CASE("nff: written reference scenes read back equal to the originals") {
  RAYNODE_REQUIRE_SCENES(dir);
  for (const char* name : {"teapot-s2.nff", "rings-s1.nff", "rings-s4.nff", "mount-s6-t6.nff",
                           "balls-s4.nff", "tetra-s1.nff"}) {
    CAPTURE(name);
    const Scene original = read_nff((dir / "spd" / name).string());
    check_same_scene(parse_nff(to_nff(original)), original);
  }
}

TEST_CASE("nff: writer reproduces every plain SPD reference file byte for byte") {
  // SPD prints %g (6 digits); fmt's shortest float form gives the same text.
  RAYNODE_REQUIRE_SCENES(dir);
  int files = 0;
  for (const ManifestRow& row : read_manifest(dir / "spd")) {
    if (row.file.ends_with(".gz")) continue;
    CAPTURE(row.file);
    const fs::path path = dir / "spd" / row.file;
    CHECK(to_nff(read_nff(path.string())) == slurp(path));
    ++files;
  }
  CHECK(files == 16);
}

// ---------------------------------------------------------------------------
// Syntax
// ---------------------------------------------------------------------------

TEST_CASE("nff: cone written on three lines parses like one line") {
  const Scene one = parse_nff("c 0 0 0 1 0 2 0 0.5\n");
  const Scene three = parse_nff("c\n0 0 0 1\n0 2 0 0.5\n");
  check_same_scene(one, three);
  REQUIRE(one.cones.size() == 1);
  CHECK(one.cones[0] == Cone{{0, 0, 0}, 1.0f, {0, 2, 0}, 0.5f});
}

TEST_CASE("nff: light colour is read when three more numbers follow, and only then") {
  const Scene s = parse_nff("l 1 2 3 0.5 0.25 1\nl 4 5 6\ns 0 0 0 1\nl 7 8 9");
  REQUIRE(s.lights.size() == 3);
  CHECK(s.lights[0] == Light{{1, 2, 3}, {0.5f, 0.25f, 1.0f}, true});
  CHECK(s.lights[1] == Light{{4, 5, 6}, {1, 1, 1}, false});
  CHECK(s.lights[2] == Light{{7, 8, 9}, {1, 1, 1}, false});
  CHECK(s.spheres.size() == 1);
  // The colour survives a round trip; the colourless lights stay colourless.
  check_same_scene(parse_nff(to_nff(s)), s);
}

TEST_CASE("nff: comments run to the end of the line, anywhere between tokens") {
  const Scene s = parse_nff(
      "# header comment\n"
      "b 0.1 0.2 0.3 # trailing comment\n"
      "s 1 # inside an entity\n"
      "  2 3 4\t#after a tab\n"
      "   # indented comment line\n"
      "p 3 0 0 0 1 0 0 0 1 0\n"
      "# last line has no newline");
  CHECK(s.background == Vec3{0.1f, 0.2f, 0.3f});
  REQUIRE(s.spheres.size() == 1);
  CHECK(s.spheres[0] == Sphere{{1, 2, 3}, 4});
  CHECK(s.counts().polygons == 1);
}

TEST_CASE("nff: numbers in exponent form, with a plus sign, or -0 parse as floats") {
  const Scene s = parse_nff("s -2.55836e-17 1E+2 +3 -0\r\n");
  REQUIRE(s.spheres.size() == 1);
  CHECK(s.spheres[0].center == Vec3{-2.55836e-17f, 100.0f, 3.0f});
  CHECK(s.spheres[0].radius == 0.0f);
  CHECK(std::signbit(s.spheres[0].radius));
}

TEST_CASE("nff: a material is a state applying to the primitives after it") {
  const Scene s = parse_nff(
      "s 0 0 0 1\n"
      "f 1 0 0 0.5 0.5 3 0 1\n"
      "s 1 0 0 1\n"
      "pp 3 0 0 0 0 0 1 1 0 0 0 0 1 0 1 0 0 0 1\n"
      "f 0 1 0 1 0 100000 0.8 1.1\n"
      "p 4 0 0 0 1 0 0 1 1 0 0 1 0\n");
  // The first sphere precedes any `f`: it gets the default material.
  REQUIRE(s.materials.size() == 3);
  CHECK(s.materials[0] == Material{});
  CHECK(s.materials[2] == Material{{0, 1, 0}, 1, 0, 100000, 0.8f, 1.1f});
  REQUIRE(s.shapes.size() == 4);
  CHECK(s.shapes[0].material == 0);
  CHECK(s.shapes[1].material == 1);
  CHECK(s.shapes[2].material == 1);
  CHECK(s.shapes[3].material == 2);
  CHECK(s.shapes[2].kind == ShapeKind::kPatch);
  CHECK(s.normals.size() == 3);
  CHECK(s.shapes[3].count == 4);
}

TEST_CASE("nff: view block labels may come in any order and set has_view") {
  const Scene s = parse_nff(
      "v\nresolution 640 480\nhither 0.5\nangle 30\nup 0 0 1\nat 1 1 1\nfrom 2 3 4\n");
  CHECK(s.has_view);
  CHECK(s.view.from == Vec3{2, 3, 4});
  CHECK(s.view.at == Vec3{1, 1, 1});
  CHECK(s.view.up == Vec3{0, 0, 1});
  CHECK(s.view.angle == 30.0f);
  CHECK(s.view.hither == 0.5f);
  CHECK(s.view.width == 640);
  CHECK(s.view.height == 480);
  CHECK_FALSE(parse_nff("s 0 0 0 1").has_view);
}

TEST_CASE("nff: degenerate polygons and patches are dropped and counted") {
  const Scene s = parse_nff(
      "p 3 0 0 0 1 0 0 2 0 0\n"                    // collinear
      "p 4 0 0 0 0 0 0 0 0 0 0 0 0\n"              // all one point
      "pp 3 0 0 0 0 0 1 1 1 1 0 0 1 1 1 1 0 0 1\n"  // repeated vertex
      "p 3 0 0 0 1 0 0 0 1 0\n");                  // fine
  CHECK(s.dropped_degenerate == 3);
  CHECK(s.counts().polygons == 1);
  CHECK(s.counts().patches == 0);
  CHECK(s.vertices.size() == 3);
  CHECK(s.normals.empty());
  CHECK(s.vertices[0] == Vec3{0, 0, 0});
  CHECK(s.vertices[1] == Vec3{1, 0, 0});
}

// ---------------------------------------------------------------------------
// Errors
// ---------------------------------------------------------------------------

TEST_CASE("nff: ParseError::what is file:line:col: message") {
  const ParseError e("scene.nff", 3, 5, "something is wrong");
  CHECK(std::string(e.what()) == "scene.nff:3:5: something is wrong");
  CHECK(e.file() == "scene.nff");
  CHECK(e.line() == 3);
  CHECK(e.column() == 5);
  CHECK(e.message() == "something is wrong");
}

TEST_CASE("nff: read_nff reports the path in its parse errors") {
  TempDir tmp;
  const fs::path p = tmp.path / "bad.nff";
  std::ofstream(p) << "b 0 0 0\nl 1 2 3\ns 1 abc 3 4\n";
  try {
    read_nff(p.string());
    FAIL("no ParseError");
  } catch (const ParseError& e) {
    CHECK(e.file() == p.string());
    CHECK(std::string(e.what()) ==
          p.string() + ":3:5: expected a number for sphere centre, found 'abc'");
  }
}

TEST_CASE("nff: unknown keyword is reported at the keyword") {
  check_error("b 0 0 0\n\n  sphere 1 2 3 4\n", 3, 3, "unknown keyword 'sphere'");
  check_error("P 3 0 0 0 1 0 0 0 1 0", 1, 1, "unknown keyword 'P'");
}

TEST_CASE("nff: extra numbers after an entity are reported at the first extra one") {
  check_error("s 1 2 3 4 5\n", 1, 11,
              "expected a keyword, found the number '5' (too many numbers in the previous "
              "entity?)");
}

TEST_CASE("nff: non-numeric token is reported at the token") {
  check_error("s 1 2 3 abc\n", 1, 9, "expected a number for sphere radius, found 'abc'");
  check_error("b 0 0 0\nl 1 2 3\ns 1 abc 3 4\n", 3, 5,
              "expected a number for sphere centre, found 'abc'");
  check_error("f 1 1 1 0.5 0.5 3.0x 0 1\n", 1, 17,
              "expected a number for material Shine, found '3.0x'");
  check_error("p 3\n0 0 0\n1 0 0\n0 1 z\n", 4, 5,
              "expected a number for polygon vertex 3, found 'z'");
  check_error("pp 3\n0 0 0 0 0 1\n1 0 0 0 , 1\n", 3, 9,
              "expected a number for patch normal 2, found ','");
  check_error("c 0 0 0 1 0 1 0 0x1", 1, 17,
              "expected a number for cone apex radius, found '0x1'");
}

TEST_CASE("nff: columns count bytes, so a tab is one column") {
  check_error("# comment\n  # another\n\ts 1 2 3 x", 3, 10,
              "expected a number for sphere radius, found 'x'");
}

TEST_CASE("nff: missing number is reported at the keyword that came instead") {
  check_error("s 1 2 3\np 3 0 0 0 1 0 0 0 1 0\n", 2, 1,
              "expected a number for sphere radius, found 'p'");
  check_error("l 1 2 3 0.5 0.5\ns 0 0 0 1\n", 2, 1,
              "expected a number for light colour, found 's'");
}

TEST_CASE("nff: nan, inf and float overflow are rejected as non-finite") {
  check_error("s 1 2 3 nan\n", 1, 9, "expected a finite number for sphere radius, found 'nan'");
  check_error("b 0 0 0\np 3\n0 0 0\n-inf 0 0\n0 1 0\n", 4, 1,
              "expected a finite number for polygon vertex 2, found '-inf'");
  check_error("s 1e39 0 0 1\n", 1, 3, "expected a finite number for sphere centre, found '1e39'");
  check_error("l 0 0 0 infinity 1 1\n", 1, 9,
              "expected a finite number for light colour, found 'infinity'");
  // Underflow is not an error: it rounds to a tiny or zero float, however
  // small (load_limits_test.cpp).
  CHECK(parse_nff("s 0 0 0 1e-50").spheres.at(0).radius == 0.0f);
  CHECK(parse_nff("s 0 0 0 1e-400").spheres.at(0).radius == 0.0f);
}

TEST_CASE("nff: polygon with fewer than 3 vertices is reported at its count") {
  check_error("p 2\n0 0 0\n1 0 0\n", 1, 3, "polygon has 2 vertices; at least 3 are needed");
  check_error("s 0 0 0 1\npp 0\n", 2, 4, "patch has 0 vertices; at least 3 are needed");
  check_error("p -4\n", 1, 3, "polygon has -4 vertices; at least 3 are needed");
  check_error("p 3.0\n0 0 0 1 0 0 0 1 0\n", 1, 3,
              "expected an integer for polygon vertex count, found '3.0'");
}

TEST_CASE("nff: absurd vertex count is reported, not allocated") {
  check_error("p 2000000000\n0 0 0\n", 1, 3,
              "polygon has 2000000000 vertices; at most 10000000 are supported");
  check_error("\npp 99999999999999999999999 0 0 0", 2, 4,
              "patch vertex count '99999999999999999999999' is out of range");
}

TEST_CASE("nff: zero or negative resolution is reported at the number") {
  const std::string view = kViewBlock;  // 6 lines; resolution is on line 7
  check_error(view + "resolution 0 512\n", 7, 12,
              "resolution width must be a positive number of pixels, found 0");
  check_error(view + "resolution 512 -5\n", 7, 16,
              "resolution height must be a positive number of pixels, found -5");
  check_error(view + "resolution 512 51.2\n", 7, 16,
              "expected an integer for resolution height, found '51.2'");
}

TEST_CASE("nff: malformed view block is reported at the offending label") {
  check_error("v\nfrom 0 0 0\nfrm 0 0 -1\n", 3, 1,
              "expected 'at' in the view block, found 'frm'");
  check_error("v\nfrom 0 0 0\nfrom 0 0 -1\n", 3, 1, "'from' appears twice in the view block");
  check_error("v\nfrom 0 0 0\nat 0 0 -1\nup 0 1 0\nangle 45\nresolution 8 8\nl 0 0 0\n", 7, 1,
              "expected 'hither' in the view block, found 'l'");
}

TEST_CASE("nff: truncated file is reported at the end of input") {
  check_error("p 3\n", 2, 1, "file ends inside a 'p' entity (expected 3 more vertices)");
  check_error("p 3\n0 0 0\n1 0", 3, 4, "file ends inside a 'p' entity (expected 2 more vertices)");
  check_error("pp 3\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0\n", 5, 1,
              "file ends inside a 'pp' entity (expected 1 more vertex)");
  check_error("b 0 0 0\np", 2, 2,
              "file ends inside a 'p' entity (expected polygon vertex count)");
  check_error("s 1 2", 1, 6, "file ends inside a 's' entity (expected sphere centre)");
  check_error("c 0 0 0 1\n0 1 0 # the apex radius is missing\n", 3, 1,
              "file ends inside a 'c' entity (expected cone apex radius)");
  check_error("l 1 2 3 0.5", 1, 12, "file ends inside a 'l' entity (expected light colour)");
  check_error("v\nfrom 0 0 0\n", 3, 1, "file ends inside a 'v' entity (expected 'at')");
  check_error(std::string(kViewBlock) + "resolution 512", 7, 15,
              "file ends inside a 'v' entity (expected resolution height)");
}

TEST_CASE("nff: unreadable file throws runtime_error naming the path and the reason") {
  TempDir tmp;
  const std::string missing = (tmp.path / "missing.nff").string();
  try {
    read_nff(missing);
    FAIL("no exception");
  } catch (const ParseError&) {
    FAIL("a missing file is not a parse error");
  } catch (const std::runtime_error& e) {
    CHECK(std::string(e.what()) == "cannot open '" + missing + "': No such file or directory");
  }
}

// ---------------------------------------------------------------------------
// Writer
// ---------------------------------------------------------------------------

TEST_CASE("nff: writer uses SPD's layout: b, v block, lights, then f and primitives") {
  const Scene s = parse_nff(
      "l 4 5 6 0.5 0.25 0.125\n"
      "f 1 0 0 0.5 0.5 3.0827 0 1\n"
      "c\n0 0 0 1\n0 2 0 0.5\n"
      "v\nfrom 1 2 3\nat 0 0 0\nup 0 0 1\nangle 45\nhither 0.01\nresolution 640 480\n"
      "b 0.1 0.2 0.3\n"
      "pp 3 0 0 0 0 0 1 1 0 0 0 0 1 0 1 0 -0 0 1\n"
      "l 1 2 3\n"
      "s 1 2 3 1e-05\n"
      "p 3 0 0 0 1 0 0 0 1 0\n");
  CHECK(to_nff(s) ==
        "b 0.1 0.2 0.3\n"
        "v\nfrom 1 2 3\nat 0 0 0\nup 0 0 1\nangle 45\nhither 0.01\nresolution 640 480\n"
        "l 4 5 6 0.5 0.25 0.125\n"
        "l 1 2 3\n"
        "f 1 0 0 0.5 0.5 3.0827 0 1\n"
        "c 0 0 0 1 0 2 0 0.5\n"
        "pp 3\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 -0 0 1\n"
        "s 1 2 3 1e-05\n"
        "p 3\n0 0 0\n1 0 0\n0 1 0\n");
}

TEST_CASE("nff: unused materials, in the middle and at the end, survive a round trip") {
  const Scene s = parse_nff(
      "f 1 0 0 1 0 0 0 1\n"
      "f 0 1 0 1 0 0 0 1\n"
      "s 0 0 0 1\n"
      "f 0 0 1 1 0 0 0 1\n"
      "f 1 1 0 1 0 0 0 1\n"
      "s 1 0 0 1\n"
      "f 0 1 1 1 0 0 0 1\n"
      "f 1 0 1 1 0 0 0 1\n");
  REQUIRE(s.materials.size() == 6);
  CHECK(s.shapes.at(0).material == 1);
  CHECK(s.shapes.at(1).material == 3);
  check_same_scene(parse_nff(to_nff(s)), s);
}

TEST_CASE("nff: a built scene with awkward floats round-trips bit for bit") {
  Scene s;
  s.background = {0.1f, 1.0f / 3.0f, 3.4028235e38f};
  s.lights.push_back({{1e-38f, -0.0f, 1.17549435e-38f}, {0.7f, 0.7f, 0.7f}, true});
  s.lights.push_back({{1.4e-45f, 123456789.0f, -7.0e-7f}, {1, 1, 1}, false});
  s.materials.push_back({{0.2f, 0.4f, 0.6f}, 0.3f, 0.7f, 1e5f, 0.9f, 1.5f});
  const Vec3 quad[4] = {{0, 0, 0}, {1.0f / 7.0f, 0, 0}, {1, 1, 0}, {0, 2.0f / 3.0f, 0}};
  s.add_polygon(quad, 4);
  s.add_sphere({{1e20f, -1e-20f, 0.5f}, 16777217.0f});
  s.materials.push_back({});
  s.add_cone({{0, 0, 0}, 2.5f, {0, 0, 9.999999f}, 0.0f});
  const Vec3 tri[3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const Vec3 nrm[3] = {{0, 0, 1}, {0, 0.70710677f, 0.70710677f}, {-0.0f, 0, 1}};
  s.add_patch(tri, nrm, 3);
  CHECK_FALSE(s.has_view);
  check_same_scene(parse_nff(to_nff(s)), s);

  s.has_view = true;
  s.view = {{1, 2, 3}, {4, 5, 6}, {0.1f, 0.9f, 0.0f}, 33.3f, 0.001f, 1, 7};
  check_same_scene(parse_nff(to_nff(s)), s);
}

TEST_CASE("nff: gzip and plain files written by write_nff_file read back identical scenes") {
  RAYNODE_REQUIRE_SCENES(dir);
  TempDir tmp;
  const Scene original = read_nff((dir / "spd" / "teapot-s2.nff").string());
  const fs::path gz = tmp.path / "teapot.nff.gz";
  const fs::path plain = tmp.path / "teapot.nff";
  write_nff_file(gz.string(), original);
  write_nff_file(plain.string(), original);
  CHECK_FALSE(fs::exists(gz.string() + ".tmp"));
  CHECK_FALSE(fs::exists(plain.string() + ".tmp"));

  const std::string gz_bytes = slurp(gz);
  REQUIRE(gz_bytes.size() > 2);
  CHECK(static_cast<unsigned char>(gz_bytes[0]) == 0x1f);
  CHECK(static_cast<unsigned char>(gz_bytes[1]) == 0x8b);
  CHECK(gz_bytes.size() < fs::file_size(plain));
  CHECK(slurp(plain) == to_nff(original));

  const Scene from_gz = read_nff(gz.string());
  check_same_scene(from_gz, read_nff(plain.string()));
  check_same_scene(from_gz, original);

  // Detection is by content, not by name.
  const fs::path renamed = tmp.path / "teapot-compressed.nff";
  fs::copy_file(gz, renamed);
  check_same_scene(read_nff(renamed.string()), original);
}

TEST_CASE("nff: truncated gzip file throws runtime_error, not a crash or a partial scene") {
  RAYNODE_REQUIRE_SCENES(dir);
  TempDir tmp;
  const fs::path gz = tmp.path / "teapot.nff.gz";
  write_nff_file(gz.string(), read_nff((dir / "spd" / "teapot-s2.nff").string()));
  fs::resize_file(gz, fs::file_size(gz) / 2);
  CHECK_THROWS_AS(read_nff(gz.string()), std::runtime_error);
}

TEST_CASE("nff: write_nff_file into a missing directory throws and leaves no file") {
  TempDir tmp;
  const fs::path target = tmp.path / "no-such-dir" / "out.nff";
  const Scene s = parse_nff("s 0 0 0 1\n");
  CHECK_THROWS_AS(write_nff_file(target.string(), s), std::runtime_error);
  CHECK_THROWS_AS(write_nff_file(target.string() + ".gz", s), std::runtime_error);
  CHECK_FALSE(fs::exists(tmp.path / "no-such-dir"));
}

TEST_CASE("nff: write_nff_file replaces an existing file") {
  TempDir tmp;
  const fs::path p = tmp.path / "scene.nff";
  write_nff_file(p.string(), parse_nff("s 0 0 0 1\n"));
  write_nff_file(p.string(), parse_nff("s 0 0 0 2\ns 0 0 0 3\n"));
  CHECK(read_nff(p.string()).spheres.size() == 2);
  CHECK(std::distance(fs::directory_iterator(tmp.path), fs::directory_iterator()) == 1);
}
