// Tests for mesh input through Assimp (core/mesh_file.h) and the view
// helpers (core/scene_view.h): small meshes written here in each format
// (OBJ + MTL, ASCII and binary PLY, ASCII and binary STL, OFF, glTF),
// triangle counts, kept normals, material mapping, the defaults for a file
// without materials, lights or view, and one-line errors on garbage and
// truncated files.
#include "core/mesh_file.h"

#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <unistd.h>

#include "core/database.h"
#include "core/nff.h"
#include "core/scene_source.h"
#include "core/scene_view.h"

namespace fs = std::filesystem;
using raynode::core::Bounds3;
using raynode::core::Material;
using raynode::core::read_mesh;
using raynode::core::Scene;
using raynode::core::ShapeKind;
using raynode::core::Vec3;
using raynode::core::View;

namespace {

/// A directory of its own under the system's temporary directory, removed at the end.
struct MeshDir {
  fs::path path;
  MeshDir() : path(fs::temp_directory_path() / ("raynode_mesh_test." + std::to_string(::getpid()))) {
    fs::create_directories(path);
  }
  ~MeshDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  /// Writes `bytes` to NAME in the directory; returns its path.
  std::string write(const std::string& name, const std::string& bytes) const {
    const fs::path p = path / name;
    std::ofstream(p, std::ios::binary) << bytes;
    return p.string();
  }
};

template <typename T>
void put(std::string& out, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  out.append(b, sizeof(T));
}

std::size_t count_kind(const Scene& s, ShapeKind k) {
  std::size_t n = 0;
  for (const auto& sh : s.shapes) n += sh.kind == k;
  return n;
}

/// The message of the std::runtime_error `f` throws ("" when none).
template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

const char* kObj =
    "mtllib m.mtl\n"
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 3 0 0\nv 2 1 0\n"
    "vn 0 0 1\nvn 0.6 0 0.8\nvn 0 0.6 0.8\nvn 0.6 0.6 0.52\n"
    "usemtl glass\n"
    "f 1//1 2//2 3//3 4//4\n"  // a quad with normals: 2 smooth triangles
    "usemtl red\n"
    "f 5 6 7\n"  // no normals: flat
    "l 1 5\n"
    "p 6\n";
const char* kMtl =
    "newmtl glass\nKd 0.2 0.4 0.6\nKs 0.5 0.5 0.5\nNs 20\nd 0.25\nNi 1.5\n"
    "newmtl red\nKd 1 0 0\nKs 0 0 0\n";

}  // namespace

TEST_CASE("mesh: OBJ with MTL keeps vertex normals, maps materials and skips points and lines") {
  MeshDir dir;
  dir.write("m.mtl", kMtl);
  const std::string path = dir.write("quad.obj", kObj);
  std::vector<std::string> notes;
  const Scene s = read_mesh(path, &notes);
  CHECK(count_kind(s, ShapeKind::kPatch) == 2);
  CHECK(count_kind(s, ShapeKind::kPolygon) == 1);
  REQUIRE(s.materials.size() == 2);
  const Material& glass = s.materials[s.shapes[0].material];
  CHECK(glass.color.x == doctest::Approx(0.2f));
  CHECK(glass.color.y == doctest::Approx(0.4f));
  CHECK(glass.color.z == doctest::Approx(0.6f));
  CHECK(glass.kd == 1.0f);
  CHECK(glass.ks == doctest::Approx(0.5f));
  CHECK(glass.shine == doctest::Approx(20.0f));
  CHECK(glass.transmittance == doctest::Approx(0.75f));
  CHECK(glass.ior == doctest::Approx(1.5f));
  const Material& red = s.materials[s.shapes[2].material];
  CHECK(red.color == Vec3{1, 0, 0});
  CHECK(red.ks == 0.0f);
  CHECK(red.transmittance == 0.0f);
  // The normals are the file's (normalised), not the face's.
  bool saw_tilted = false;
  for (const Vec3& n : s.normals) saw_tilted |= n.x == doctest::Approx(0.6f) && n.z == doctest::Approx(0.8f);
  CHECK(saw_tilted);
  // No lights, no view in an OBJ: both filled in and reported; a point and a line skipped.
  CHECK(s.lights.size() == 2);
  CHECK(s.has_view);
  std::string all;
  for (const auto& n : notes) all += n + "\n";
  CHECK(all.find("has no view: framing its bounding box from +z") != std::string::npos);
  CHECK(all.find("has no lights") != std::string::npos);
  CHECK(all.find("skipped 1 points and 1 lines") != std::string::npos);
  CHECK(all.find("has no materials") == std::string::npos);
}

TEST_CASE("mesh: ASCII PLY with normals gives smooth triangles and the default material") {
  MeshDir dir;
  const std::string path = dir.write("n.ply",
                                     "ply\nformat ascii 1.0\nelement vertex 4\n"
                                     "property float x\nproperty float y\nproperty float z\n"
                                     "property float nx\nproperty float ny\nproperty float nz\n"
                                     "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
                                     "0 0 0 0 0 1\n1 0 0 0.6 0 0.8\n1 1 0 0 0.6 0.8\n0 1 0 0 0 1\n"
                                     "4 0 1 2 3\n3 0 2 3\n");
  std::vector<std::string> notes;
  const Scene s = read_mesh(path, &notes);
  CHECK(count_kind(s, ShapeKind::kPatch) == 3);
  CHECK(count_kind(s, ShapeKind::kPolygon) == 0);
  REQUIRE(s.materials.size() == 1);
  CHECK(s.materials[0].color == Vec3{0.8f, 0.8f, 0.8f});
  CHECK(s.materials[0].kd == 1.0f);
  CHECK(s.materials[0].ks == 0.0f);
  REQUIRE(!notes.empty());
  CHECK(notes[0] == path + " has no materials: using grey (colour 0.8 0.8 0.8, Kd 1)");
}

TEST_CASE("mesh: binary PLY without normals is flat, degenerate triangles dropped") {
  MeshDir dir;
  std::string b =
      "ply\nformat binary_little_endian 1.0\nelement vertex 4\n"
      "property float x\nproperty float y\nproperty float z\n"
      "element face 2\nproperty list uchar int vertex_indices\nend_header\n";
  for (float v : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f, 2.f, 0.f, 0.f}) put(b, v);
  put(b, std::uint8_t(3)), put(b, std::int32_t(0)), put(b, std::int32_t(1)), put(b, std::int32_t(2));
  put(b, std::uint8_t(3)), put(b, std::int32_t(0)), put(b, std::int32_t(1)), put(b, std::int32_t(3));  // collinear
  const Scene s = read_mesh(dir.write("b.ply", b));
  CHECK(count_kind(s, ShapeKind::kPolygon) == 1);
  CHECK(s.dropped_degenerate == 1);
  CHECK(s.normals.empty());
  CHECK(s.counts().dropped_degenerate == 1);
}

TEST_CASE("mesh: big-endian PLY with double coordinates, extra properties and elements") {
  MeshDir dir;
  std::string b =
      "ply\r\nformat binary_big_endian 1.0\r\ncomment made by hand\r\nelement vertex 3\r\n"
      "property double x\r\nproperty double y\r\nproperty double z\r\nproperty uchar red\r\n"
      "element face 1\r\nproperty list uchar uint vertex_indices\r\nproperty float quality\r\n"
      "element edge 1\r\nproperty int vertex1\r\nproperty int vertex2\r\nend_header\r\n";
  auto put_be = [&b](auto v) {
    char c[sizeof v];
    std::memcpy(c, &v, sizeof v);
    for (std::size_t i = sizeof v; i-- > 0;) b.push_back(c[i]);
  };
  const double xyz[3][3] = {{0, 0, 0}, {4, 0, 0}, {0, 2, 0}};
  for (const auto& v : xyz) {
    for (double x : v) put_be(x);
    put_be(std::uint8_t(200));
  }
  put_be(std::uint8_t(3)), put_be(std::uint32_t(0)), put_be(std::uint32_t(1)), put_be(std::uint32_t(2));
  put_be(0.5f);
  put_be(std::int32_t(0)), put_be(std::int32_t(1));
  const Scene s = read_mesh(dir.write("be.ply", b));
  REQUIRE(s.shapes.size() == 1);
  CHECK(s.bounds().upper.x == 4.0f);
  CHECK(s.bounds().upper.y == 2.0f);
  // Cut anywhere inside the body: an error, never a crash.
  const std::size_t body = b.find("end_header\r\n") + 12;
  for (std::size_t cut = body; cut < b.size(); cut += 7) {
    CAPTURE(cut);
    const std::string path = dir.write("cut.ply", b.substr(0, cut));
    CHECK(error_of([&] { read_mesh(path); }).find("(truncated)") != std::string::npos);
  }
}

TEST_CASE("mesh: ASCII and binary STL give flat triangles") {
  MeshDir dir;
  const std::string ascii = dir.write("a.stl",
                                      "solid t\n"
                                      "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
                                      "endloop\nendfacet\n"
                                      "facet normal 0 0 1\nouter loop\nvertex 1 0 0\nvertex 1 1 0\nvertex 0 1 0\n"
                                      "endloop\nendfacet\nendsolid t\n");
  const Scene a = read_mesh(ascii);
  CHECK(count_kind(a, ShapeKind::kPolygon) == 2);
  CHECK(count_kind(a, ShapeKind::kPatch) == 0);
  REQUIRE(a.materials.size() == 1);  // Assimp's stand-in material becomes raynode's grey
  CHECK(a.materials[0].color == Vec3{0.8f, 0.8f, 0.8f});
  CHECK(a.materials[0].ks == 0.0f);

  std::string b(80, 'x');  // a header that does not start with "solid"
  put(b, std::uint32_t(3));
  for (int t = 0; t < 3; ++t) {
    for (float v : {0.f, 0.f, 1.f}) put(b, v);  // facet normal
    for (float v : {float(t), 0.f, 0.f, float(t) + 1, 0.f, 0.f, float(t), 1.f, 0.f}) put(b, v);
    put(b, std::uint16_t(0));
  }
  const Scene s = read_mesh(dir.write("b.stl", b));
  CHECK(count_kind(s, ShapeKind::kPolygon) == 3);
  CHECK(s.bounds().upper.x == 3.0f);
}

TEST_CASE("mesh: OFF polygons are triangulated") {
  MeshDir dir;
  const Scene s = read_mesh(dir.write("q.off", "OFF\n5 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n4 0 1 2 3\n3 0 1 4\n"));
  CHECK(s.shapes.size() == 3);
  CHECK(count_kind(s, ShapeKind::kPolygon) == 3);
}

TEST_CASE("mesh: glTF applies node transforms and maps the base colour") {
  MeshDir dir;
  // One triangle (0,0,0) (1,0,0) (0,1,0) in an embedded buffer, its node moved by +10 in x.
  const std::string gltf = R"({
  "asset": {"version": "2.0"},
  "scene": 0, "scenes": [{"nodes": [0]}],
  "nodes": [{"mesh": 0, "translation": [10, 0, 0]}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "material": 0}]}],
  "materials": [{"name": "blue", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.25, 1.0, 1.0]}}],
  "buffers": [{"byteLength": 36, "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36, "target": 34962}],
  "accessors": [{"bufferView": 0, "byteOffset": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                 "max": [1.0, 1.0, 0.0], "min": [0.0, 0.0, 0.0]}]
})";
  const Scene s = read_mesh(dir.write("t.gltf", gltf));
  REQUIRE(s.shapes.size() == 1);
  const Bounds3 b = s.bounds();
  CHECK(b.lower.x == 10.0f);
  CHECK(b.upper.x == 11.0f);
  CHECK(b.upper.y == 1.0f);
  const Material& m = s.materials[s.shapes[0].material];
  CHECK(m.color.x == doctest::Approx(0.5f));
  CHECK(m.color.y == doctest::Approx(0.25f));
  CHECK(m.color.z == doctest::Approx(1.0f));
  CHECK(m.transmittance == 0.0f);
}

TEST_CASE("mesh: the framed view sees the whole bounding box from +z") {
  MeshDir dir;
  const Scene s = read_mesh(dir.write("q.off", "OFF\n3 1 0\n-2 0 5\n2 0 5\n0 3 5\n3 0 1 2\n"));
  REQUIRE(s.has_view);
  CHECK(s.view.at == Vec3{0.0f, 1.5f, 5.0f});
  CHECK(s.view.from.x == 0.0f);
  CHECK(s.view.from.y == 1.5f);
  CHECK(s.view.from.z > 5.0f);
  CHECK(s.view.up == Vec3{0, 1, 0});
  CHECK(s.view.angle == 45.0f);
  // The bounding sphere (radius 2.5) fits the 45-degree cone: sin(22.5) * distance >= radius.
  const double distance = double(s.view.from.z - 5.0f);
  CHECK(std::sin(22.5 * 3.14159265358979 / 180.0) * distance >= 2.5 * 0.999);
  // The default lights stand above the eye, off to both sides.
  REQUIRE(s.lights.size() == 2);
  CHECK(s.lights[0].position.y > s.view.from.y);
  CHECK(s.lights[0].position.x > 0.0f);
  CHECK(s.lights[1].position.x < 0.0f);
}

TEST_CASE("mesh: the NFF a mesh scene writes reads back as the same scene") {
  MeshDir dir;
  dir.write("m.mtl", kMtl);
  const Scene s = read_mesh(dir.write("quad.obj", kObj));
  const std::string out = (dir.path / "quad.nff").string();
  raynode::core::write_nff_file(out, s);
  const Scene t = raynode::core::read_nff(out);
  CHECK(t.counts() == s.counts());
  CHECK(t.view == s.view);
  CHECK(t.materials == s.materials);
  CHECK(t.normals == s.normals);
}

TEST_CASE("mesh: files are recognised by extension and by their first bytes") {
  MeshDir dir;
  CHECK(raynode::core::is_mesh_extension("a.OBJ"));
  CHECK(raynode::core::is_mesh_extension("dir/a.ply"));
  CHECK(raynode::core::is_mesh_extension("a.glb"));
  CHECK_FALSE(raynode::core::is_mesh_extension("a.nff"));
  CHECK_FALSE(raynode::core::is_mesh_extension("a.nff.gz"));
  CHECK_FALSE(raynode::core::is_mesh_extension("teapot"));
  CHECK(raynode::core::is_scene_file("bunny.ply"));  // a file, even before it exists
  CHECK_FALSE(raynode::core::is_scene_file("teapot:8"));
  const std::string ply = dir.write("noext",
                                    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                    "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                                    "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  CHECK(raynode::core::is_mesh_file(ply));
  const std::string nff = dir.write("plain", "s 0 0 0 1\n");
  CHECK_FALSE(raynode::core::is_mesh_file(nff));
  CHECK(raynode::core::load_scene(ply).shapes.size() == 1);
  CHECK(raynode::core::load_scene(nff).counts().spheres == 1);
}

TEST_CASE("mesh: garbage and truncated files of each format are one error naming the file") {
  MeshDir dir;
  std::string bin_ply =
      "ply\nformat binary_little_endian 1.0\nelement vertex 30\n"
      "property float x\nproperty float y\nproperty float z\n"
      "element face 10\nproperty list uchar int vertex_indices\nend_header\n";
  put(bin_ply, 1.0f);
  std::string bin_stl(80, 'x');
  put(bin_stl, std::uint32_t(1000));
  for (int i = 0; i < 20; ++i) put(bin_stl, 1.0f);
  static const char kGarbage[] = "\x01\xff\xfe garbage \x00\x1bX\n\x7f\x80";  // with a NUL inside
  const std::string garbage(kGarbage, sizeof kGarbage - 1);
  const std::vector<std::pair<std::string, std::string>> files = {
      {"g.obj", garbage},
      {"cut.obj", "v 0 0 0\nv 1 0 0\nf 1 2 7\n"},
      {"g.ply", garbage},
      {"cut.ply", bin_ply},
      {"cuta.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                   "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0"},
      {"g.stl", garbage},
      {"cut.stl", bin_stl},
      {"cuta.stl", "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0"},
      {"g.off", garbage},
      {"cut.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n"},
      {"g.gltf", garbage},
      {"cut.gltf", R"({"asset": {"version": "2.0"}, "meshes": [{"primitives": [{"attributes": )"},
      {"g.glb", garbage},
      {"cut.glb", std::string("glTF\x02\x00\x00\x00\xff\x00\x00\x00", 12)},
      {"empty.ply", ""},
  };
  for (const auto& [name, bytes] : files) {
    CAPTURE(name);
    const std::string path = dir.write(name, bytes);
    const std::string what = error_of([&] { read_mesh(path); });
    CHECK(what.find("cannot read mesh '" + path + "'") == 0);
    CHECK(what.find('\n') == std::string::npos);
  }
  CHECK(error_of([&] { read_mesh((dir.path / "missing.obj").string()); }).find("missing.obj") != std::string::npos);
}

TEST_CASE("view override: any subset of eye, at, up, fov replaces the scene's view") {
  Scene s = raynode::core::parse_nff(
      "v\nfrom 0 0 10\nat 0 0 0\nup 0 1 0\nangle 30\nhither 0\nresolution 64 32\ns 0 0 0 1\n");
  raynode::core::ViewOverride o;
  o.eye = Vec3{5, 0, 0};
  o.fov = 60.0f;
  raynode::core::apply_view_override(s, o);
  CHECK(s.view.from == Vec3{5, 0, 0});
  CHECK(s.view.at == Vec3{0, 0, 0});
  CHECK(s.view.up == Vec3{0, 1, 0});
  CHECK(s.view.angle == 60.0f);
  CHECK(s.view.width == 64);
  CHECK(s.view.height == 32);

  Scene none = raynode::core::parse_nff("s 1 2 3 1\n");
  raynode::core::ViewOverride fov;
  fov.fov = 20.0f;
  raynode::core::apply_view_override(none, fov);
  CHECK(none.has_view);
  CHECK(none.view.angle == 20.0f);
  CHECK(none.view.at == Vec3{1, 2, 3});  // the default view's target
}

TEST_CASE("view override: an unusable view is refused with the values") {
  const Scene base = raynode::core::parse_nff("v\nfrom 0 0 10\nat 0 0 0\nup 0 1 0\nangle 30\nhither 0\n"
                                              "resolution 8 8\ns 0 0 0 1\n");
  auto refusal = [&](const raynode::core::ViewOverride& o) {
    Scene s = base;
    try {
      raynode::core::apply_view_override(s, o);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  raynode::core::ViewOverride same;
  same.eye = Vec3{0, 0, 0};
  CHECK(refusal(same) == "the view with --eye cannot be used: 'at' (0, 0, 0) is the same point as 'from'");
  raynode::core::ViewOverride parallel;
  parallel.up = Vec3{0, 0, 2};
  CHECK(refusal(parallel).find("'up' (0, 0, 2) is parallel to the viewing direction (0, 0, -10)") !=
        std::string::npos);
  raynode::core::ViewOverride wide;
  wide.fov = 180.0f;
  CHECK(refusal(wide) == "the view with --fov cannot be used: field of view 180 must be in (0, 180) degrees");
}

TEST_CASE("fit_resolution: one side given keeps the view's aspect ratio") {
  View v;
  v.width = 512;
  v.height = 256;
  int w = 64, h = 0;
  raynode::core::fit_resolution(w, h, v);
  CHECK(w == 64);
  CHECK(h == 32);
  w = 0, h = 100;
  raynode::core::fit_resolution(w, h, v);
  CHECK(w == 200);
  w = 3, h = 0;
  raynode::core::fit_resolution(w, h, v);
  CHECK(h == 2);  // 1.5 rounds away from zero
  w = 0, h = 0;
  raynode::core::fit_resolution(w, h, v);
  CHECK(w == 0);
  CHECK(h == 0);
  w = 1, h = 0;
  v.height = 1;
  raynode::core::fit_resolution(w, h, v);
  CHECK(h == 1);  // at least one pixel
}

TEST_CASE("mesh: a camera given with the file places the default lights beside its eye") {
  MeshDir dir;
  const std::string path = dir.write("q.off", "OFF\n3 1 0\n-2 0 5\n2 0 5\n0 3 5\n3 0 1 2\n");
  raynode::core::ViewOverride o;
  o.eye = Vec3{100, 0, 5};
  o.at = Vec3{0, 1, 5};
  std::vector<std::string> notes;
  const Scene s = read_mesh(path, &notes, o);
  CHECK(s.view.from == Vec3{100, 0, 5});
  CHECK(s.view.at == Vec3{0, 1, 5});
  REQUIRE(s.lights.size() == 2);
  CHECK(s.lights[0].position.x > 100.0f);  // behind-right of the eye on +x, not near the +z framing
  CHECK(s.lights[1].position.x > 100.0f);
  for (const auto& n : notes) CHECK(n.find("has no view") == std::string::npos);
}
