// The tracer's answers on fixed scenes and rays, printed one line per ray:
// closest hit (primitive, t, u, v as bit patterns), any-hit, and the cells,
// tests and empty-space jumps each query counted. Built twice (tests/
// CMakeLists.txt): at the build's -march, where the walk's set-up and jumps
// run in SSE lanes and the packed cells in AVX lanes, and at -march=x86-64
// (SSE2 only), where the walk takes its scalar form and the lane tests run
// in 128-bit halves. The two outputs must be byte-identical: every form of
// the walk and of the tests performs the same operations in the same order
// (traverse.h, cell_blocks.h), so a build for an older CPU
// (RAYNODE_ARCH=x86-64-v2 or empty) renders the same images.
//
// The view is a type of this file's own (a DirectView), so that the
// traversal is instantiated here, under this file's flags, and not taken
// from raynode_core's compiled copy.
#include <bit>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "core/cell_blocks.h"
#include "core/database.h"
#include "core/direct_view.h"
#include "core/grid.h"
#include "core/scene.h"
#include "core/scene_source.h"
#include "core/traverse.h"
#include "random_scene.h"
#include "test_grid_params.h"

using namespace raynode::core;

namespace {

struct LocalView : DirectView {
  using DirectView::DirectView;
};

using raynode::testing::grid::random_in;
using raynode::testing::grid::Rng;

std::uint32_t bits(float f) { return std::bit_cast<std::uint32_t>(f); }

// Rays into and through `box`: from outside and inside, some along an axis
// or with zero components, some on cell boundaries of a 4x4x4 split.
std::vector<Ray> rays_for(const Bounds3& box, std::uint64_t seed, int n) {
  Rng rng(seed);
  const Vec3 e = box.extent();
  const Bounds3 around{box.lower - e * 0.3f, box.upper + e * 0.3f};
  std::vector<Ray> rays;
  for (int i = 0; i < n; ++i) {
    Vec3 o = random_in(rng, i % 3 == 0 ? box : around);
    Vec3 d = random_in(rng, box) - o;
    switch (i % 7) {
      case 1: d = {d.x, 0.0f, d.z}; break;                  // a zero component
      case 2: d = {0.0f, 0.0f, d.z < 0 ? -1.0f : 1.0f}; break;  // along an axis
      case 3: o.x = box.lower.x + e.x * 0.25f * float(i % 5); break;  // on a boundary plane
      default: break;
    }
    if (!(d.x != 0.0f || d.y != 0.0f || d.z != 0.0f)) d = {1, 0, 0};
    rays.push_back(Ray{o, d, 0.0f, kInfinity});
  }
  return rays;
}

void dump(const char* name, const Database& db, const GridParams& gp, std::uint32_t pack_min, PackKinds kinds) {
  const Grid grid = build_grid(db, gp);
  const CellBlocks blocks = pack_min > 0 ? build_cell_blocks(db, grid, pack_min, kinds) : CellBlocks{};
  const LocalView view(db, grid, pack_min > 0 ? &blocks : nullptr);
  TraversalScratch scratch;
  std::printf("# %s: %s grid, %zu sub-grids, %zu primitives, packed from %u\n", name, grid_kind_name(grid.kind()),
              grid.sub_grid_count(), db.primitives.size(), pack_min);
  int line = 0;
  for (const Ray& ray : rays_for(db.bounds, 7 + db.primitives.size(), 1500)) {
    const TraversalStats before = scratch.stats;
    Hit hit;
    const bool found = intersect_closest(view, ray, hit, scratch);
    Ray shadow = ray;
    shadow.tmax = found ? hit.t * 0.5f : 2.0f;
    const bool any = intersect_any(view, shadow, scratch);
    const TraversalStats& s = scratch.stats;
    std::printf("%d %d %u %08x %08x %08x %d %llu %llu %llu %llu %llu\n", line++, int(found), hit.primitive, bits(hit.t),
                bits(hit.u), bits(hit.v), int(any),
                static_cast<unsigned long long>(s.cells_visited - before.cells_visited),
                static_cast<unsigned long long>(s.empty_jumps - before.empty_jumps),
                static_cast<unsigned long long>(s.triangle_tests - before.triangle_tests),
                static_cast<unsigned long long>(s.sphere_tests + s.cone_tests - before.sphere_tests - before.cone_tests),
                static_cast<unsigned long long>(s.mailbox_skips - before.mailbox_skips));
  }
}

}  // namespace

int main() {
  GridParams uniform_grid;
  uniform_grid.kind = GridKind::kUniform;
  GridParams adaptive_grid;
  adaptive_grid.kind = GridKind::kAdaptive;
  const GridParams deep = raynode::testing::small_scene_sub_grids(4, true);  // sub-grids two levels deep on small scenes

  const Database teapot = make_database(load_scene({"teapot:3", 0}));
  const Database rings = make_database(load_scene({"rings:2", 0}));
  const Database mixed = make_database(raynode::testing::grid::random_scene(3, 1500, 150, 80, 0.04f));
  dump("teapot:3", teapot, uniform_grid, 0, PackKinds::kTriangles);
  dump("teapot:3", teapot, adaptive_grid, 1, PackKinds::kTriangles);
  dump("teapot:3", teapot, deep, 1, PackKinds::kTriangles);
  dump("rings:2", rings, uniform_grid, 0, PackKinds::kTriangles);
  dump("rings:2", rings, deep, 1, PackKinds::kTrianglesAndSpheres);
  dump("soup", mixed, uniform_grid, 1, PackKinds::kTrianglesAndSpheres);
  dump("soup", mixed, deep, 0, PackKinds::kTriangles);
  dump("soup", mixed, deep, 1, PackKinds::kTrianglesAndSpheres);
  return 0;
}
