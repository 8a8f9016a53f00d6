// Tests for spd::make_teapot against the NFF files SPD 3.14 `teapot -s N`
// wrote (../shared/scenes/spd/teapot-s{2,7,8}.nff, read with core::read_nff).
//
// Tolerance: SPD prints %g (6 significant digits), raynode stores floats, so
// two numbers a (reference) and b (generated) agree when
//   |a - b| <= 1e-4 * max(1, |a|, |b|)
// i.e. 1e-4 relative, with an absolute floor of 1e-4 for |a|, |b| < 1 (the
// files hold noise such as 1.4538e-15 where the exact value is 0).
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/nff.h"
#include "core/spd_generators.h"
#include "scenes_dir.h"

namespace {

using raynode::core::Material;
using raynode::core::Scene;
using raynode::core::SceneCounts;
using raynode::core::Shape;
using raynode::core::ShapeKind;
using raynode::core::Vec3;

constexpr double kRelTol = 1e-4;

bool close(double a, double b) {
  return std::fabs(a - b) <= kRelTol * std::max({1.0, std::fabs(a), std::fabs(b)});
}

bool close(const Vec3& a, const Vec3& b) {
  return close(a.x, b.x) && close(a.y, b.y) && close(a.z, b.z);
}

std::string str(const Vec3& v) {
  std::ostringstream os;
  os.precision(9);
  os << "(" << v.x << ", " << v.y << ", " << v.z << ")";
  return os.str();
}

std::string str(const Material& m) {
  std::ostringstream os;
  os.precision(9);
  os << "f " << str(m.color) << " kd " << m.kd << " ks " << m.ks << " shine " << m.shine << " T "
     << m.transmittance << " ior " << m.ior;
  return os.str();
}

bool close(const Material& a, const Material& b) {
  return close(a.color, b.color) && close(a.kd, b.kd) && close(a.ks, b.ks) &&
         close(a.shine, b.shine) && close(a.transmittance, b.transmittance) && close(a.ior, b.ior);
}

/// The MANIFEST.tsv row for `file`, as counts (dropped_degenerate 0: SPD's
/// files hold no zero-area polygon for the reader to drop).
SceneCounts manifest_counts(const std::filesystem::path& dir, const std::string& file) {
  std::ifstream in(dir / "spd" / "MANIFEST.tsv");
  REQUIRE_MESSAGE(in, "cannot open MANIFEST.tsv");
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header;
  {
    std::istringstream hs(line);
    for (std::string col; std::getline(hs, col, '\t');) header.push_back(col);
  }
  auto column = [&](const std::string& name) {
    const auto it = std::find(header.begin(), header.end(), name);
    REQUIRE_MESSAGE(it != header.end(), "MANIFEST.tsv has no column " << name);
    return static_cast<std::size_t>(it - header.begin());
  };
  while (std::getline(in, line)) {
    std::vector<std::string> cols;
    std::istringstream ls(line);
    for (std::string col; std::getline(ls, col, '\t');) cols.push_back(col);
    if (cols.empty() || cols[0] != file) continue;
    auto num = [&](const std::string& name) {
      return static_cast<std::size_t>(std::stoul(cols.at(column(name))));
    };
    SceneCounts c;
    c.polygons = num("polygons");
    c.patches = num("patches");
    c.spheres = num("spheres");
    c.cones = num("cones");
    c.lights = num("lights");
    c.materials = num("materials");
    return c;
  }
  FAIL("MANIFEST.tsv has no row for " << file);
  return {};
}

/// Vertex normals of `scene`'s patches that point away from their
/// triangle's geometric normal (v1 - v0) x (v2 - v0), i.e. dot <= 0.
/// `region_ok` is told each offending triangle's vertices.
template <class RegionCheck>
int count_disagreeing_normals(const Scene& scene, RegionCheck region_ok) {
  int bad = 0;
  for (const Shape& s : scene.shapes) {
    if (s.kind != ShapeKind::kPatch) continue;
    const Vec3* v = &scene.vertices[s.first];
    const Vec3* n = &scene.normals[s.first_normal];
    const Vec3 g = cross(v[1] - v[0], v[2] - v[0]);
    bool any = false;
    for (std::uint32_t i = 0; i < s.count; ++i) {
      if (dot(g, n[i]) <= 0.0f) {
        ++bad;
        any = true;
      }
    }
    if (any) region_ok(v);
  }
  return bad;
}

/// Compares the generated scene with the reference entity by entity.
void check_matches_reference(const Scene& ref, const Scene& gen) {
  CHECK(gen.has_view == ref.has_view);
  CHECK_MESSAGE(close(gen.view.from, ref.view.from), str(gen.view.from) << " vs " << str(ref.view.from));
  CHECK_MESSAGE(close(gen.view.at, ref.view.at), str(gen.view.at) << " vs " << str(ref.view.at));
  CHECK_MESSAGE(close(gen.view.up, ref.view.up), str(gen.view.up) << " vs " << str(ref.view.up));
  CHECK(close(gen.view.angle, ref.view.angle));
  CHECK(close(gen.view.hither, ref.view.hither));
  CHECK(gen.view.width == ref.view.width);
  CHECK(gen.view.height == ref.view.height);
  CHECK_MESSAGE(close(gen.background, ref.background),
                str(gen.background) << " vs " << str(ref.background));

  REQUIRE(gen.lights.size() == ref.lights.size());
  for (std::size_t i = 0; i < ref.lights.size(); ++i) {
    CHECK_MESSAGE(close(gen.lights[i].position, ref.lights[i].position),
                  "light " << i << ": " << str(gen.lights[i].position) << " vs "
                           << str(ref.lights[i].position));
    CHECK(gen.lights[i].has_color == ref.lights[i].has_color);
  }

  REQUIRE(gen.materials.size() == ref.materials.size());
  for (std::size_t i = 0; i < ref.materials.size(); ++i) {
    CHECK_MESSAGE(close(gen.materials[i], ref.materials[i]),
                  "material " << i << ": " << str(gen.materials[i]) << " vs "
                              << str(ref.materials[i]));
  }

  REQUIRE(gen.shapes.size() == ref.shapes.size());
  std::size_t mismatched_shapes = 0;
  double worst = 0.0;  // largest |a - b| / max(1, |a|, |b|) seen
  auto track = [&worst](const Vec3& a, const Vec3& b) {
    for (int k = 0; k < 3; ++k) {
      const double d = std::fabs(double(a[k]) - b[k]) /
                       std::max({1.0, std::fabs(double(a[k])), std::fabs(double(b[k]))});
      worst = std::max(worst, d);
    }
  };
  for (std::size_t i = 0; i < ref.shapes.size(); ++i) {
    const Shape& r = ref.shapes[i];
    const Shape& g = gen.shapes[i];
    bool ok = r.kind == g.kind && r.count == g.count && r.material == g.material;
    if (ok) {
      for (std::uint32_t k = 0; k < r.count; ++k) {
        const Vec3& rv = ref.vertices[r.first + k];
        const Vec3& gv = gen.vertices[g.first + k];
        track(rv, gv);
        ok = ok && close(rv, gv);
        if (r.kind == ShapeKind::kPatch) {
          const Vec3& rn = ref.normals[r.first_normal + k];
          const Vec3& gn = gen.normals[g.first_normal + k];
          track(rn, gn);
          ok = ok && close(rn, gn);
        }
      }
    }
    if (!ok && ++mismatched_shapes <= 5) {
      std::ostringstream os;
      os << "shape " << i << " differs: kind/count/material " << int(r.kind) << "/" << r.count
         << "/" << r.material << " vs " << int(g.kind) << "/" << g.count << "/" << g.material;
      if (r.count == g.count) {
        for (std::uint32_t k = 0; k < r.count; ++k)
          os << "\n  v" << k << " " << str(ref.vertices[r.first + k]) << " vs "
             << str(gen.vertices[g.first + k]);
      }
      FAIL_CHECK(os.str());
    }
  }
  CHECK(mismatched_shapes == 0);
  MESSAGE("largest scaled deviation from the reference: " << worst);
  CHECK(worst <= kRelTol);
}

struct Reference {
  int size;
  const char* file;
};

constexpr Reference kReferences[] = {
    {2, "teapot-s2.nff"},
    {7, "teapot-s7.nff"},
    {8, "teapot-s8.nff"},
};

}  // namespace

TEST_CASE("spd teapot: counts per kind equal SPD's MANIFEST and the reference files") {
  RAYNODE_REQUIRE_SCENES(dir);
  for (const Reference& r : kReferences) {
    const std::string file = r.file;
    CAPTURE(file);
    const SceneCounts want = manifest_counts(dir, r.file);
    const Scene ref = raynode::core::read_nff((dir / "spd" / r.file).string());
    const Scene gen = raynode::core::spd::make_teapot(r.size);
    CHECK(ref.counts() == want);
    CHECK(gen.counts() == want);
    // SPD's formula (teapot.c): n^2 squares, 64 n^2 - 8 n triangles.
    CHECK(gen.counts().polygons == std::size_t(r.size * r.size));
    CHECK(gen.counts().patches == std::size_t(64 * r.size * r.size - 8 * r.size));
  }
}

TEST_CASE("spd teapot: s2, s7, s8 equal SPD's NFF entity by entity within 1e-4 relative") {
  RAYNODE_REQUIRE_SCENES(dir);
  for (const Reference& r : kReferences) {
    const std::string file = r.file;
    CAPTURE(file);
    const Scene ref = raynode::core::read_nff((dir / "spd" / r.file).string());
    const Scene gen = raynode::core::spd::make_teapot(r.size);
    check_matches_reference(ref, gen);
  }
}

TEST_CASE("spd teapot: cusp triangles dropped and cusp normals straight up (lid) / down (bottom)") {
  for (int size : {2, 7, 8}) {
    CAPTURE(size);
    const Scene gen = raynode::core::spd::make_teapot(size);
    int lid = 0, bottom = 0;
    for (const Shape& s : gen.shapes) {
      if (s.kind != ShapeKind::kPatch) continue;
      int on_axis = 0;
      for (std::uint32_t k = 0; k < s.count; ++k) {
        const Vec3& v = gen.vertices[s.first + k];
        if (std::fabs(v.x) > 1e-4f || std::fabs(v.y) > 1e-4f) continue;
        ++on_axis;
        const Vec3& n = gen.normals[s.first_normal + k];
        if (v.z > 1.5f) {
          ++lid;
          CHECK(n == Vec3{0.0f, 0.0f, 1.0f});
        } else {
          ++bottom;
          CHECK(n == Vec3{0.0f, 0.0f, -1.0f});
        }
      }
      CHECK(on_axis <= 1);  // two cusp vertices = zero area: must have been dropped
    }
    // 4 lid patches and 4 bottom patches each keep `size` triangles touching the cusp.
    CHECK(lid == 4 * size);
    CHECK(bottom == 4 * size);
  }
}

TEST_CASE("spd teapot: pp geometric normal (v1-v0)x(v2-v0) agrees with the vertex normals") {
  // The NFF notes claim this for every teapot `pp`. It holds from SPD's
  // default size 6 up (checked through 64), and in teapot-s7/s8, but NOT at
  // sizes 2..5: at size 2, 28 vertex normals in 16 triangles on the spout tip
  // (x >= 2.8) and the lid knob (z >= 2.98) point away from their coarse
  // triangle, in SPD's own teapot-s2.nff exactly as here.
  for (int size : {6, 7, 8, 12, 16}) {
    CAPTURE(size);
    const Scene gen = raynode::core::spd::make_teapot(size);
    CHECK(count_disagreeing_normals(gen, [](const Vec3*) {}) == 0);
  }
  auto spout_tip_or_knob = [](const Vec3* v) {
    const bool spout = v[0].x >= 2.79f && v[1].x >= 2.79f && v[2].x >= 2.79f;
    const bool knob = v[0].z >= 2.98f && v[1].z >= 2.98f && v[2].z >= 2.98f;
    CHECK_MESSAGE((spout || knob), "disagreeing triangle outside spout tip / lid knob: "
                                       << str(v[0]) << " " << str(v[1]) << " " << str(v[2]));
  };
  const Scene gen2 = raynode::core::spd::make_teapot(2);
  CHECK(count_disagreeing_normals(gen2, spout_tip_or_knob) == 28);

  RAYNODE_REQUIRE_SCENES(dir);
  for (const Reference& r : kReferences) {
    const std::string file = r.file;
    CAPTURE(file);
    const Scene ref = raynode::core::read_nff((dir / "spd" / r.file).string());
    CHECK(count_disagreeing_normals(ref, spout_tip_or_knob) == (r.size == 2 ? 28 : 0));
  }
}

TEST_CASE("spd teapot: sizes out of range throw std::invalid_argument with the reason") {
  for (int size : {-1, 0, 1}) {
    CAPTURE(size);
    try {
      (void)raynode::core::spd::make_teapot(size);
      FAIL("no exception");
    } catch (const std::invalid_argument& e) {
      const std::string what = e.what();
      CHECK_MESSAGE(what.find("unsupported") != std::string::npos, what);
      CHECK_MESSAGE(what.find("minimum 2") != std::string::npos, what);
    }
  }
  for (int size : {65, 1000000}) {
    CAPTURE(size);
    try {
      (void)raynode::core::spd::make_teapot(size);
      FAIL("no exception");
    } catch (const std::invalid_argument& e) {
      const std::string what = e.what();
      CHECK_MESSAGE(what.find("maximum 64") != std::string::npos, what);
    }
  }
  CHECK_NOTHROW((void)raynode::core::spd::make_teapot(64));
}
