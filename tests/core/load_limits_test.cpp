// Tests of loading under hostile input (scene_file.h, nff.h, database.h,
// tessellate, grid): every loading phase honours the stop request, a FIFO or
// a device is read without blocking past it, gzip inflates within a limit
// whatever its trailer says, `#` inside a token is no comment, underflow
// rounds to zero, and long polygons triangulate in O(n) when convex and are
// refused with a message when concave.
#include <doctest/doctest.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "core/database.h"
#include "core/grid.h"
#include "core/nff.h"
#include "core/scene.h"
#include "core/scene_file.h"
#include "core/scene_source.h"
#include "core/spd.h"
#include "core/stop.h"

namespace fs = std::filesystem;
using namespace raynode::core;

namespace {

constexpr const char* kSmallScene = "v from 0 0 5 at 0 0 0 up 0 1 0 angle 40 hither 1 resolution 4 4\n"
                                    "l 1 1 5\nf 1 0 0 1 0 0 0 1\ns 0 0 0 1\n";

/// A fresh empty directory for one test, removed afterwards.
struct TempDir {
  fs::path path;
  explicit TempDir(const std::string& name)
      : path(fs::temp_directory_path() / (name + "." + std::to_string(::getpid()))) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  std::string file(const std::string& name) const { return (path / name).string(); }
};

/// Calls request_stop() from another thread after `delay`, and clears the
/// request when the test is done.
struct StopLater {
  std::thread thread;
  explicit StopLater(std::chrono::milliseconds delay)
      : thread([delay] {
          std::this_thread::sleep_for(delay);
          request_stop("the test's deadline passed");
        }) {}
  ~StopLater() {
    thread.join();
    clear_stop_request();
  }
};

/// Clears the stop request on every way out of a test that set it.
struct ClearStop {
  ~ClearStop() { clear_stop_request(); }
};

/// gzip (one member) of `text`, in memory.
std::string gzip(const std::string& text) {
  z_stream zs{};
  REQUIRE(deflateInit2(&zs, 9, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) == Z_OK);
  std::string out(deflateBound(&zs, uLong(text.size())), '\0');
  zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(text.data()));
  zs.avail_in = uInt(text.size());
  zs.next_out = reinterpret_cast<Bytef*>(out.data());
  zs.avail_out = uInt(out.size());
  REQUIRE(deflate(&zs, Z_FINISH) == Z_STREAM_END);
  out.resize(zs.total_out);
  deflateEnd(&zs);
  return out;
}

void write_file(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

std::string what_of_stop(const std::function<void()>& f) {
  try {
    f();
  } catch (const StopError& e) {
    return e.what();
  }
  return "(no StopError)";
}

/// Vertices of a square of side `side` with `per_side` vertices on each side
/// (integer coordinates, exact in float): convex, with collinear vertices.
std::vector<Vec3> square_polygon(std::uint32_t per_side, float side) {
  std::vector<Vec3> v;
  const float step = side / float(per_side);
  for (std::uint32_t i = 0; i < per_side; ++i) v.push_back({float(i) * step, 0, 0});
  for (std::uint32_t i = 0; i < per_side; ++i) v.push_back({side, float(i) * step, 0});
  for (std::uint32_t i = 0; i < per_side; ++i) v.push_back({side - float(i) * step, side, 0});
  for (std::uint32_t i = 0; i < per_side; ++i) v.push_back({0, side - float(i) * step, 0});
  return v;
}

/// A star: n vertices alternating between radius 1 and 0.5 (concave for n >= 6).
std::vector<Vec3> star_polygon(std::uint32_t n) {
  std::vector<Vec3> v;
  for (std::uint32_t i = 0; i < n; ++i) {
    const double a = 2 * 3.141592653589793 * i / n;
    const double r = i % 2 ? 0.5 : 1.0;
    v.push_back({float(r * std::cos(a)), float(r * std::sin(a)), 0});
  }
  return v;
}

std::string polygon_nff(const std::vector<Vec3>& v) {
  std::string s = "p " + std::to_string(v.size()) + "\n";
  for (const Vec3& p : v) s += fmt::format("{} {} {}\n", p.x, p.y, p.z);
  return s;
}

double summed_area(const std::vector<Vec3>& v, const std::vector<std::uint32_t>& tris) {
  double area = 0;
  for (std::size_t t = 0; t < tris.size(); t += 3) {
    const Vec3 a = v[tris[t]], b = v[tris[t + 1]], c = v[tris[t + 2]];
    area += 0.5 * ((double(b.x) - a.x) * (double(c.y) - a.y) - (double(b.y) - a.y) * (double(c.x) - a.x));
  }
  return area;
}

}  // namespace

// --- Numbers -------------------------------------------------------------------

TEST_CASE("nff numbers: '#' inside a token is part of it, so 1.#INF is a non-finite number, not 1") {
  try {
    parse_nff("s 0 0 0 1.#INF\n", "inf.nff");
    FAIL("1.#INF was read");
  } catch (const ParseError& e) {
    CHECK(std::string(e.what()) == "inf.nff:1:9: expected a finite number for sphere radius, found '1.#INF'");
  }
  CHECK_THROWS_WITH(parse_nff("s 0 0 0 -1.#IND00\n"), doctest::Contains("expected a finite number for sphere radius, found '-1.#IND00'"));
  CHECK_THROWS_WITH(parse_nff("l 0 0 0 1.#QNAN 1 1\n"), doctest::Contains("expected a finite number for light colour, found '1.#QNAN'"));
  // Any other glued '#' makes the token a bad number.
  CHECK_THROWS_WITH(parse_nff("s 0 0 0 4#note\n"), doctest::Contains("1:9: expected a number for sphere radius, found '4#note'"));
  // At a token start '#' still starts a comment.
  CHECK(parse_nff("s 0 0 0 4 #note\n").spheres.at(0).radius == 4.0f);
}

TEST_CASE("nff numbers: underflow follows one rule, IEEE rounding: 1e-50 and 1e-400 both read as a signed zero") {
  const Scene s = parse_nff("s 1e-50 1e-400 -1e-400 1e-99999999999999999999999\n");
  REQUIRE(s.spheres.size() == 1);
  CHECK(s.spheres[0].center.x == 0.0f);
  CHECK(s.spheres[0].center.y == 0.0f);
  CHECK(s.spheres[0].center.z == 0.0f);
  CHECK(std::signbit(s.spheres[0].center.z));
  CHECK(s.spheres[0].radius == 0.0f);
  // A denormal stays a denormal, and 0.0000001e-39 is 1e-46: below half the smallest denormal, zero.
  const Scene d = parse_nff("s 1e-40 8e-46 0.0000001e-39 1\n");
  CHECK(d.spheres.at(0).center.x == doctest::Approx(1e-40f).epsilon(1e-4));
  CHECK(d.spheres.at(0).center.y == std::numeric_limits<float>::denorm_min());
  CHECK(d.spheres.at(0).center.z == 0.0f);
  // Overflow is still an error, however written.
  CHECK_THROWS_WITH(parse_nff("s 1e400 0 0 1\n"), doctest::Contains("expected a finite number for sphere centre, found '1e400'"));
  CHECK_THROWS_WITH(parse_nff("s 0.00001e45 0 0 1\n"), doctest::Contains("found '0.00001e45'"));
}

// --- FIFOs and devices ------------------------------------------------------------

TEST_CASE("scene file: a FIFO with a writer is read to its end and parsed") {
  TempDir dir("raynode_fifo_writer");
  const std::string fifo = dir.file("scene.fifo");
  REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
  std::thread writer([&] {
    const int fd = ::open(fifo.c_str(), O_WRONLY);  // blocks until the reader opens
    if (fd < 0) return;
    const std::string text = kSmallScene;
    // In two pieces with a pause: the reader must wait for the rest, not stop.
    (void)!::write(fd, text.data(), 20);
    std::this_thread::sleep_for(std::chrono::milliseconds(150));
    (void)!::write(fd, text.data() + 20, text.size() - 20);
    ::close(fd);
  });
  const Scene s = read_nff(fifo);
  writer.join();
  CHECK(s.has_view);
  CHECK(s.spheres.size() == 1);
  CHECK(s.lights.size() == 1);
  CHECK(is_scene_file(fifo));
}

TEST_CASE("scene file: a FIFO with no writer stops at the stop request with the path named, instead of blocking") {
  TempDir dir("raynode_fifo_silent");
  const std::string fifo = dir.file("silent.fifo");
  REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
  const std::string what = [&] {
    StopLater stop(std::chrono::milliseconds(200));
    return what_of_stop([&] { read_nff(fifo); });
  }();
  CHECK(what == "the test's deadline passed: stopped while reading '" + fifo + "' (a FIFO)");
}

TEST_CASE("scene file: a device that never ends is read up to the limit, then refused with the limit named") {
  try {
    read_scene_text("/dev/zero", std::size_t(1) << 20);
    FAIL("/dev/zero was read to the end");
  } catch (const std::runtime_error& e) {
    CHECK(std::string(e.what()).rfind("cannot read '/dev/zero': the character device sent more than 1 MiB", 0) == 0);
  }
  CHECK(read_scene_text("/dev/null", 1 << 20).empty());
}

TEST_CASE("scene file: a regular file above the limit is refused before it is read, a directory by name") {
  TempDir dir("raynode_big_file");
  write_file(dir.file("big.nff"), std::string(3 << 20, ' '));
  CHECK_THROWS_WITH(read_scene_text(dir.file("big.nff"), 1 << 20),
                    doctest::Contains("big.nff': it is 3 MiB, more than 1 MiB"));
  CHECK(read_scene_text(dir.file("big.nff"), 4 << 20).size() == (3u << 20));
  CHECK_THROWS_WITH(read_scene_text(dir.path.string(), 1 << 20), doctest::Contains("Is a directory"));
}

TEST_CASE("scene file: the default limit is a quarter of what the process may allocate, at least 16 MiB") {
  const std::size_t limit = scene_text_limit_bytes();
  CHECK(limit >= (std::size_t(16) << 20));
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
  CHECK(limit <= std::max(std::size_t(pages) * std::size_t(page) / 4, std::size_t(16) << 20));
}

// --- gzip --------------------------------------------------------------------------

TEST_CASE("gzip: a size trailer claiming 4 GiB allocates nothing like it, the data decides") {
  std::string gz = gzip(kSmallScene);
  // The last 4 bytes are ISIZE; 0xffffffff claims 4 GiB - 1.
  for (std::size_t i = gz.size() - 4; i < gz.size(); ++i) gz[i] = '\xff';
  // zlib checks ISIZE at the end of the member: the lie is reported, with
  // nothing sized from it (a 1 MiB limit would refuse any such buffer).
  CHECK_THROWS_WITH(gunzip_bytes(gz, "fake.nff.gz", 1 << 20),
                    doctest::Contains("cannot decompress 'fake.nff.gz': incorrect length check"));
  CHECK(gunzip_bytes(gzip(kSmallScene), "good.nff.gz", 1 << 20) == kSmallScene);
}

TEST_CASE("gzip: data inflating past the limit is refused with the path and the limit in MiB") {
  const std::string gz = gzip(std::string(std::size_t(5) << 20, ' '));  // ~5 KiB that inflate to 5 MiB
  CHECK(gz.size() < 64 * 1024);
  try {
    gunzip_bytes(gz, "bomb.nff.gz", std::size_t(2) << 20);
    FAIL("the bomb was inflated");
  } catch (const std::runtime_error& e) {
    CHECK(std::string(e.what()).rfind("cannot decompress 'bomb.nff.gz': it inflates to more than 2 MiB", 0) == 0);
  }
  CHECK(gunzip_bytes(gz, "bomb.nff.gz", std::size_t(5) << 20).size() == (std::size_t(5) << 20));  // exactly fits
  // Two concatenated members still inflate to both.
  CHECK(gunzip_bytes(gzip("s 0 0 0 1\n") + gzip("s 1 1 1 1\n"), "two.gz", 1 << 20) == "s 0 0 0 1\ns 1 1 1 1\n");
}

TEST_CASE("gzip: inflating stops at the stop request") {
  ClearStop clear;
  const std::string gz = gzip(std::string(std::size_t(4) << 20, ' '));
  request_stop("stop now");
  CHECK(what_of_stop([&] { gunzip_bytes(gz, "g.nff.gz", std::size_t(8) << 20); }) ==
        "stop now: stopped while decompressing 'g.nff.gz'");
}

// --- Stop request in every loading phase ------------------------------------------

TEST_CASE("stop request: reading, parsing, tessellating, making the database and building the grid each stop") {
  ClearStop clear;
  TempDir dir("raynode_stop_phases");
  std::string text;
  for (int i = 0; i < 5000; ++i) text += "s " + std::to_string(i) + " 0 0 0.5\n";
  write_file(dir.file("many.nff"), text);
  const Scene scene = read_nff(dir.file("many.nff"));
  REQUIRE(scene.spheres.size() == 5000);
  const Database db = make_database(scene);
  request_stop("deadline");
  CHECK(what_of_stop([&] { read_nff(dir.file("many.nff")); }) ==
        "deadline: stopped while reading '" + dir.file("many.nff") + "'");
  CHECK(what_of_stop([&] { parse_nff(text, "many.nff"); }) == "deadline: stopped while parsing 'many.nff'");
  CHECK(what_of_stop([&] {
          Scene s = scene;
          tessellate_scene(s, 2);
        }) == "deadline: stopped while tessellating the scene (-t 2)");
  CHECK(what_of_stop([&] { make_database(scene); }) ==
        "deadline: stopped while making the database (triangulating polygons)");
  CHECK(what_of_stop([&] { build_grid(db, GridParams{}); }).rfind(
            "deadline: stopped while building the grid (5000 primitives, ", 0) == 0);
  clear_stop_request();
  CHECK_NOTHROW(build_grid(db, GridParams{}));
}

TEST_CASE("stop request: triangulating a long polygon stops inside it") {
  ClearStop clear;
  request_stop("deadline");
  std::vector<std::uint32_t> tris;
  const std::vector<Vec3> square = square_polygon(5000, 5000);
  CHECK(what_of_stop([&] { triangulate_polygon(square.data(), std::uint32_t(square.size()), tris); }) ==
        "deadline: stopped while triangulating a polygon of 20000 vertices");
  const std::vector<Vec3> star = star_polygon(4000);
  CHECK(what_of_stop([&] { triangulate_polygon(star.data(), std::uint32_t(star.size()), tris); }) ==
        "deadline: stopped while triangulating a polygon of 4000 vertices");
}

// --- Triangulation -----------------------------------------------------------------

TEST_CASE("triangulation: a convex polygon is ear-clipped up to 1024 vertices, split in balance above") {
  // Ear clipping of a convex polygon clips vertex 0, 1, ... against the last
  // vertex: a fan around n-1 whose last triangle is (n-3, n-2, n-1). Above
  // kEarClippingVertices: (0, n/2, n-1), then the same within each chain.
  using Triangles = std::vector<std::uint32_t>;
  auto add = [](Triangles& t, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    t.push_back(a);
    t.push_back(b);
    t.push_back(c);
  };
  auto fan = [&](std::uint32_t n) {
    Triangles t;
    for (std::uint32_t k = 0; k + 3 < n; ++k) add(t, n - 1, k, k + 1);
    add(t, n - 3, n - 2, n - 1);
    return t;
  };
  auto balanced = [&](std::uint32_t n) {
    Triangles t;
    std::function<void(std::uint32_t, std::uint32_t)> split = [&](std::uint32_t i, std::uint32_t j) {
      if (j - i < 2) return;
      const std::uint32_t m = i + (j - i) / 2;
      add(t, i, m, j);
      split(i, m);
      split(m, j);
    };
    split(0, n - 1);
    return t;
  };
  auto expected = [&](std::uint32_t n) { return n > kEarClippingVertices ? balanced(n) : fan(n); };
  for (const std::uint32_t n : {5u, 64u, kEarClippingVertices, kEarClippingVertices + 1, 5000u}) {
    CAPTURE(n);
    std::vector<Vec3> v;  // a circle: strictly convex at these counts
    for (std::uint32_t i = 0; i < n; ++i) {
      const double a = 2 * 3.141592653589793 * i / n;
      v.push_back({float(10 * std::cos(a)), 2.0f, float(-10 * std::sin(a))});  // in the xz plane, either facing
    }
    REQUIRE(splits_in_linear_time(v.data(), n));
    std::vector<std::uint32_t> tris;
    triangulate_polygon(v.data(), n, tris, false);
    CHECK(tris == expected(n));
  }
}

TEST_CASE("triangulation: a convex polygon of 300000 vertices with collinear runs is split in O(n), covering its area") {
  const std::vector<Vec3> v = square_polygon(75000, 75000);
  const auto n = std::uint32_t(v.size());
  REQUIRE(n == 300000);
  CHECK(splits_in_linear_time(v.data(), n));
  std::vector<std::uint32_t> tris;
  triangulate_polygon(v.data(), n, tris, false);
  // n - 2 triangles covering the square once (those along the apex's own sides have no area).
  CHECK(tris.size() == 3 * std::size_t(n - 2));
  CHECK(summed_area(v, tris) == doctest::Approx(75000.0 * 75000.0).epsilon(1e-12));
  // Through the reader: the polygon becomes triangles with no error; the
  // (nearly) zero-area ones are dropped as for any polygon.
  std::vector<std::uint32_t> kept;
  triangulate_polygon(v.data(), n, kept);
  CHECK(kept.size() < tris.size());
  const Scene s = parse_nff(polygon_nff(v), "square.nff");
  CHECK(make_database(s).primitives.size() == kept.size() / 3);
}

TEST_CASE("triangulation: convex and star-shaped polygons split in linear time, a many-pointed star does not") {
  // A fat 5-pointed star is seen whole from an inner corner; a 20-pointed one is not.
  const std::vector<Vec3> fat = star_polygon(10);
  CHECK(splits_in_linear_time(fat.data(), 10));
  const std::vector<Vec3> star = star_polygon(40);
  CHECK_FALSE(splits_in_linear_time(star.data(), 40));
  const std::vector<Vec3> square = square_polygon(4, 4);
  CHECK(splits_in_linear_time(square.data(), 16));
  // A pac-man: concave, but every vertex is seen from its last vertex, the centre.
  std::vector<Vec3> pacman;
  for (int i = 0; i <= 300; ++i) {
    const double a = 0.5 + (2 * 3.141592653589793 - 1.0) * i / 300;
    pacman.push_back({float(std::cos(a)), float(std::sin(a)), 0});
  }
  pacman.push_back({0, 0, 0});
  CHECK(splits_in_linear_time(pacman.data(), std::uint32_t(pacman.size())));
  std::rotate(pacman.begin(), pacman.end() - 1, pacman.end());  // the centre first: the balanced split covers it
  CHECK(splits_in_linear_time(pacman.data(), std::uint32_t(pacman.size())));
}

TEST_CASE("triangulation: a 300000-vertex circle whose float coordinates zig-zag is still split in linear time") {
  // At this count consecutive turns are ~2e-5 rad: float rounding makes some
  // of them turn right, so the outline is no longer convex, yet the fan
  // covers it but for a few tiny triangles.
  std::vector<Vec3> v;
  const std::uint32_t n = 300000;
  for (std::uint32_t i = 0; i < n; ++i) {
    const double a = 2 * 3.141592653589793 * i / n;
    v.push_back({float(100 * std::cos(a)), float(100 * std::sin(a)), 7.0f});
  }
  CHECK(splits_in_linear_time(v.data(), n));
  const Scene s = parse_nff(polygon_nff(v), "circle.nff");
  CHECK(make_database(s).primitives.size() > n / 2);
  // Written with 6 significant digits the outline zig-zags more (2186 of the
  // fan's triangles turn over, 2.9e-6 of the area): still within the tolerance.
  std::string six = "p 300000\n";
  for (const Vec3& p : v) six += fmt::format("{:.6g} {:.6g} {:.6g}\n", p.x, p.y, p.z);
  CHECK(make_database(parse_nff(six, "circle6.nff")).primitives.size() > n / 2);
}

TEST_CASE("triangulation: a concave polygon above the cap is refused, by the reader at its location with the numbers") {
  const std::vector<Vec3> star = star_polygon(kMaxConcavePolygonVertices + 2);
  std::vector<std::uint32_t> tris;
  CHECK_THROWS_WITH_AS(triangulate_polygon(star.data(), std::uint32_t(star.size()), tris),
                       doctest::Contains("a polygon of 20002 vertices is not convex; a concave polygon may have at most "
                                         "20000 vertices (ear clipping takes time quadratic in the count), unless it "
                                         "is star-shaped from its last vertex"),
                       std::invalid_argument);
  try {
    parse_nff("b 0 0 0\n" + polygon_nff(star), "star.nff");
    FAIL("the star was read");
  } catch (const ParseError& e) {
    CHECK(std::string(e.what()) ==
          "star.nff:2:3: polygon has 20002 vertices and is not convex; a concave polygon may have at most 20000 "
          "vertices (triangulating one takes time quadratic in its vertices) unless it is star-shaped from its last "
          "vertex: split it");
  }
  // Below the cap a concave polygon is ear-clipped into n-2 triangles covering it.
  const std::vector<Vec3> small = star_polygon(2000);
  tris.clear();
  triangulate_polygon(small.data(), 2000, tris, false);
  CHECK(tris.size() == 3 * 1998);
  double area = 0;
  for (std::uint32_t i = 0; i < 2000; ++i) {
    const Vec3 a = small[i], b = small[(i + 1) % 2000];
    area += 0.5 * (double(a.x) * b.y - double(b.x) * a.y);
  }
  CHECK(summed_area(small, tris) == doctest::Approx(area).epsilon(1e-9));
}
