#include "core/grid.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <numbers>
#include <span>
#include <stdexcept>
#include <string>

#include "core/intersect.h"
#include "core/stop.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

namespace raynode::core {

Bounds3 GridInfo::cell_bounds(int x, int y, int z) const {
  const int c[3] = {x, y, z};
  Bounds3 b;
  for (int a = 0; a < 3; ++a) {
    b.lower[a] = bounds.lower[a] + c[a] * cell_size[a];
    b.upper[a] = (c[a] + 1 == res[a]) ? bounds.upper[a] : bounds.lower[a] + (c[a] + 1) * cell_size[a];
  }
  return b;
}

const char* grid_kind_name(GridKind kind) { return kind == GridKind::kAdaptive ? "adaptive" : "uniform"; }

std::uint32_t Grid::depth() const {
  std::uint32_t d = 0;
  for (const SubGrid& s : sub_grids) d = std::max(d, s.level);
  return d;
}

std::size_t Grid::empty_cells() const {
  std::size_t n = 0;
  for (std::size_t c = 0; c + 1 < cell_start.size(); ++c) n += cell_start[c] == cell_start[c + 1];
  return n;
}

void choose_grid_resolution(const Bounds3& bounds, std::size_t primitive_count, const GridParams& params,
                            int res[3]) {
  if (params.resolution[0] > 0 && params.resolution[1] > 0 && params.resolution[2] > 0) {
    for (int a = 0; a < 3; ++a) res[a] = std::min(params.resolution[a], params.max_resolution);
    return;
  }
  const Vec3 e = bounds.extent();
  const double emax = std::max(1e-30, double(max_component(e)));
  double volume = 1.0;
  int live_axes = 0;
  for (int a = 0; a < 3; ++a) {
    if (e[a] > 1e-3 * emax) {
      volume *= e[a];
      ++live_axes;
    }
  }
  const double cells = std::max(1.0, double(params.density) * double(std::max<std::size_t>(primitive_count, 1)));
  const double per_unit = live_axes > 0 ? std::pow(cells / volume, 1.0 / live_axes) : 0.0;
  for (int a = 0; a < 3; ++a) {
    int r = 1;
    if (e[a] > 1e-3 * emax) r = static_cast<int>(std::lround(e[a] * per_unit));
    res[a] = std::clamp(r, 1, std::max(1, params.max_resolution));
  }
}

namespace {

// Separating-axis test in double (Akenine-Moeller 2001, "Fast 3D
// Triangle-Box Overlap Testing"): 3 box normals, the triangle normal, 9 edge
// cross products.
bool tri_box_sat(const double v[3][3], const double c[3], const double h[3]) {
  double p[3][3];
  for (int i = 0; i < 3; ++i)
    for (int a = 0; a < 3; ++a) p[i][a] = v[i][a] - c[a];
  // Box face normals.
  for (int a = 0; a < 3; ++a) {
    const double lo = std::min({p[0][a], p[1][a], p[2][a]});
    const double hi = std::max({p[0][a], p[1][a], p[2][a]});
    if (lo > h[a] || hi < -h[a]) return false;
  }
  double e[3][3];
  for (int i = 0; i < 3; ++i)
    for (int a = 0; a < 3; ++a) e[i][a] = p[(i + 1) % 3][a] - p[i][a];
  // Triangle normal.
  const double n[3] = {e[0][1] * e[1][2] - e[0][2] * e[1][1], e[0][2] * e[1][0] - e[0][0] * e[1][2],
                       e[0][0] * e[1][1] - e[0][1] * e[1][0]};
  {
    const double d = n[0] * p[0][0] + n[1] * p[0][1] + n[2] * p[0][2];
    const double r = h[0] * std::fabs(n[0]) + h[1] * std::fabs(n[1]) + h[2] * std::fabs(n[2]);
    if (d > r || d < -r) return false;
  }
  // Edge x box-axis.
  for (int i = 0; i < 3; ++i) {
    for (int a = 0; a < 3; ++a) {
      double axis[3] = {0, 0, 0};
      // axis = unit_a x e_i
      const int b = (a + 1) % 3, cc = (a + 2) % 3;
      axis[b] = -e[i][cc];
      axis[cc] = e[i][b];
      const double d0 = axis[0] * p[0][0] + axis[1] * p[0][1] + axis[2] * p[0][2];
      const double d1 = axis[0] * p[1][0] + axis[1] * p[1][1] + axis[2] * p[1][2];
      const double d2 = axis[0] * p[2][0] + axis[1] * p[2][1] + axis[2] * p[2][2];
      const double r = h[0] * std::fabs(axis[0]) + h[1] * std::fabs(axis[1]) + h[2] * std::fabs(axis[2]);
      if (std::min({d0, d1, d2}) > r || std::max({d0, d1, d2}) < -r) return false;
    }
  }
  return true;
}

}  // namespace

bool triangle_overlaps_box(const Vec3& v0, const Vec3& v1, const Vec3& v2, const Bounds3& box) {
  const double v[3][3] = {{v0.x, v0.y, v0.z}, {v1.x, v1.y, v1.z}, {v2.x, v2.y, v2.z}};
  double c[3], h[3];
  for (int a = 0; a < 3; ++a) {
    c[a] = 0.5 * (double(box.lower[a]) + box.upper[a]);
    h[a] = 0.5 * (double(box.upper[a]) - box.lower[a]);
  }
  return tri_box_sat(v, c, h);
}

namespace {

// Centre and inflated half-width, per axis, of the cells lo[a]..hi[a] a
// primitive's box spans: computed once per primitive and axis, so that the
// membership tests below cost a few adds per cell. Reused across primitives
// (the builders own one).
struct CellSpans {
  std::vector<double> c[3], h[3];
};

// Fills `s` for cells lo[a]..hi[a] of `info` inflated by eps[a]: cell i's
// box on axis a is [l, u] = lower + (i, i + 1) * cell_size, centre
// (l + u) / 2, half-width (u - l) / 2 + eps[a].
void fill_cell_spans(const GridInfo& info, const double eps[3], const int lo[3], const int hi[3], CellSpans& s) {
  for (int a = 0; a < 3; ++a) {
    const auto n = std::size_t(hi[a] - lo[a] + 1);
    s.c[a].resize(n);
    s.h[a].resize(n);
    const double base = double(info.bounds.lower[a]), size = double(info.cell_size[a]);
    for (std::size_t i = 0; i < n; ++i) {
      const int idx = lo[a] + int(i);
      const double l = base + double(idx) * size;
      const double u = base + double(idx + 1) * size;
      s.c[a][i] = 0.5 * (l + u);
      s.h[a][i] = 0.5 * (u - l) + eps[a];
    }
  }
}

// Sphere membership (Arvo 1990): the squared distance from the centre to
// the cell box is at most r^2 and the box is not entirely inside the
// sphere (the surface must cross it). The squared distances add per-axis
// terms, so they are tabulated per axis and a row of cells whose nearest
// (farthest) cell is already too far (entirely inside) is skipped whole.
template <class F, class Poll>
void sphere_cells(const Primitive& p, const int lo[3], const int hi[3], CellSpans& s, std::size_t& work, F&& f,
                  Poll&& poll) {
  const double r = std::fabs(double(p.radius()));
  const double r2 = r * r;
  // Per axis a and cell i: near[a][i] and far[a][i], the squared distance
  // on that axis to the nearest and farthest point of the cell's slab.
  // Stored over the centre and half-width arrays, which are not needed after.
  double min_near[3], max_far[3];
  for (int a = 0; a < 3; ++a) {
    const double q = double(p.data[a]);
    min_near[a] = std::numeric_limits<double>::infinity();
    max_far[a] = 0;
    for (std::size_t i = 0; i < s.c[a].size(); ++i) {
      const double lo_a = s.c[a][i] - s.h[a][i], hi_a = s.c[a][i] + s.h[a][i];
      const double dl = q - lo_a, dh = hi_a - q;
      const double near = q < lo_a ? dl * dl : (q > hi_a ? dh * dh : 0.0);
      const double far_d = std::max(std::fabs(dl), std::fabs(dh));
      s.c[a][i] = near;
      s.h[a][i] = far_d * far_d;
      min_near[a] = std::min(min_near[a], near);
      max_far[a] = std::max(max_far[a], far_d * far_d);
    }
  }
  const std::vector<double>&near_x = s.c[0], &far_x = s.h[0];
  for (int z = lo[2]; z <= hi[2]; ++z) {
    const double nz = s.c[2][std::size_t(z - lo[2])], fz = s.h[2][std::size_t(z - lo[2])];
    for (int y = lo[1]; y <= hi[1]; ++y) {
      if ((++work & 4095u) == 0) poll();
      const double ny = s.c[1][std::size_t(y - lo[1])], fy = s.h[1][std::size_t(y - lo[1])];
      // Sums in x, y, z order (the per-cell test's order); adding is
      // monotone, so the row's bounds bound every cell's sum.
      if ((min_near[0] + ny) + nz > r2 || (max_far[0] + fy) + fz < r2) continue;
      for (int x = lo[0]; x <= hi[0]; ++x) {
        const std::size_t i = std::size_t(x - lo[0]);
        if ((near_x[i] + ny) + nz <= r2 && (far_x[i] + fy) + fz >= r2) f(x, y, z);
      }
    }
  }
}

// Triangle membership: the separating-axis test of tri_box_sat
// (Akenine-Moeller 2001) with every term that depends on the triangle
// alone computed once: the vertices' extents on the box normals, the
// normal's and the nine edge axes' projections of the vertices. A cell then
// costs its centre's projections; the three edge axes normal to x do not
// depend on x and are tested once per row. Same axes and inflated boxes as
// tri_box_sat, so the same cells up to the last bits of rounding.
//
// `inner` is an axis on which the triangle lies within one cell's slab (or
// -1). Then a cell's box meets the triangle if and only if its rectangle on
// the other two axes meets the triangle's projection there, and the test
// is that plane's separating-axis test: the two slabs and the three edges
// crossed with axis `inner`.
template <class F, class Poll>
void triangle_cells(const Primitive& p, const int lo[3], const int hi[3], const CellSpans& s, int inner,
                    std::size_t& work, F&& f, Poll&& poll) {
  double v[3][3];
  for (int k = 0; k < 3; ++k)
    for (int a = 0; a < 3; ++a) v[k][a] = double(p.data[3 * k + a]);
  double vmin[3], vmax[3];
  for (int a = 0; a < 3; ++a) {
    vmin[a] = std::min({v[0][a], v[1][a], v[2][a]});
    vmax[a] = std::max({v[0][a], v[1][a], v[2][a]});
  }
  double e[3][3], ae[3][3];
  for (int k = 0; k < 3; ++k)
    for (int a = 0; a < 3; ++a) {
      e[k][a] = v[(k + 1) % 3][a] - v[k][a];
      ae[k][a] = std::fabs(e[k][a]);
    }
  const double n[3] = {e[0][1] * e[1][2] - e[0][2] * e[1][1], e[0][2] * e[1][0] - e[0][0] * e[1][2],
                       e[0][0] * e[1][1] - e[0][1] * e[1][0]};
  const double an[3] = {std::fabs(n[0]), std::fabs(n[1]), std::fabs(n[2])};
  const double nv0 = n[0] * v[0][0] + n[1] * v[0][1] + n[2] * v[0][2];
  // Edge k x unit axis a projects P to e[k][b] * P[c] - e[k][c] * P[b]
  // (b = a + 1, c = a + 2 mod 3); the vertices' range on it.
  double pmin[3][3], pmax[3][3];
  for (int k = 0; k < 3; ++k)
    for (int a = 0; a < 3; ++a) {
      if (inner >= 0 && a != inner) continue;  // not tested
      const int b = (a + 1) % 3, c = (a + 2) % 3;
      double lo_p = std::numeric_limits<double>::infinity(), hi_p = -lo_p;
      for (int j = 0; j < 3; ++j) {
        const double d = e[k][b] * v[j][c] - e[k][c] * v[j][b];
        lo_p = std::min(lo_p, d);
        hi_p = std::max(hi_p, d);
      }
      pmin[k][a] = lo_p;
      pmax[k][a] = hi_p;
    }
  // Separated on edge k x axis a, for the cell whose centre and half-width
  // are (cb, hb) on axis b and (cc, hc) on axis c.
  const auto separated = [&](int k, int a, double cb, double hb, double cc, double hc) {
    const int b = (a + 1) % 3, c = (a + 2) % 3;
    const double pc = e[k][b] * cc - e[k][c] * cb;
    const double r = hb * ae[k][c] + hc * ae[k][b];
    return pmin[k][a] - pc > r || pmax[k][a] - pc < -r;
  };
  const auto slab_separated = [&](int a, double c, double h) { return vmin[a] - c > h || vmax[a] - c < -h; };
  const bool x_edges = inner < 1;  // the edges crossed with x are tested (per row)
  for (int z = lo[2]; z <= hi[2]; ++z) {
    const double cz = s.c[2][std::size_t(z - lo[2])], hz = s.h[2][std::size_t(z - lo[2])];
    if (slab_separated(2, cz, hz)) continue;
    for (int y = lo[1]; y <= hi[1]; ++y) {
      if ((++work & 4095u) == 0) poll();
      const double cy = s.c[1][std::size_t(y - lo[1])], hy = s.h[1][std::size_t(y - lo[1])];
      if (slab_separated(1, cy, hy)) continue;
      if (x_edges && (separated(0, 0, cy, hy, cz, hz) || separated(1, 0, cy, hy, cz, hz) ||
                      separated(2, 0, cy, hy, cz, hz)))
        continue;
      if (inner == 0) {  // the row's one cell (lo[0] == hi[0]): its plane's test is done
        f(lo[0], y, z);
        continue;
      }
      if (inner > 0) {
        for (int x = lo[0]; x <= hi[0]; ++x) {
          const double cx = s.c[0][std::size_t(x - lo[0])], hx = s.h[0][std::size_t(x - lo[0])];
          if (slab_separated(0, cx, hx)) continue;
          bool sep = false;
          for (int k = 0; k < 3 && !sep; ++k)
            sep = inner == 1 ? separated(k, 1, cz, hz, cx, hx) : separated(k, 2, cx, hx, cy, hy);
          if (!sep) f(x, y, z);
        }
        continue;
      }
      const double n_yz = n[1] * cy + n[2] * cz, r_yz = an[1] * hy + an[2] * hz;
      for (int x = lo[0]; x <= hi[0]; ++x) {
        const double cx = s.c[0][std::size_t(x - lo[0])], hx = s.h[0][std::size_t(x - lo[0])];
        if (slab_separated(0, cx, hx)) continue;
        const double d = nv0 - (n[0] * cx + n_yz), r = an[0] * hx + r_yz;
        if (d > r || d < -r) continue;
        bool sep = false;
        for (int k = 0; k < 3 && !sep; ++k)
          sep = separated(k, 1, cz, hz, cx, hx) || separated(k, 2, cx, hx, cy, hy);
        if (!sep) f(x, y, z);
      }
    }
  }
}

// Conservative cell membership of primitive `p`, whose bounds are `pb`, in
// the grid `info` whose cells are inflated by eps[a] on axis a: calls
// f(x, y, z) for every cell its surface may touch, in z, y, x order, and
// poll() every 4096 rows of cells tested (a row: at most one axis's cells) or
// one-cell primitives. `spans` is scratch.
template <class F, class Poll>
void for_each_overlapped_cell(const GridInfo& info, const double eps[3], const Primitive& p, const Bounds3& pb,
                              CellSpans& spans, std::size_t& work, F&& f, Poll&& poll) {
  const Bounds3& b = info.bounds;
  int lo[3], hi[3];
  int inner = 0;       // axes on which the box, unclamped, lies within one cell
  int inner_axis = -1;  // the last of them
  for (int a = 0; a < 3; ++a) {
    const double l = (double(pb.lower[a]) - eps[a] - b.lower[a]) * info.inv_cell_size[a];
    const double h = (double(pb.upper[a]) + eps[a] - b.lower[a]) * info.inv_cell_size[a];
    lo[a] = clamped_floor(l, info.res[a]);
    hi[a] = clamped_floor(h, info.res[a]);
    if (lo[a] == hi[a] && l >= 0.0 && h < double(info.res[a])) ++inner, inner_axis = a;
  }
  if (lo[0] == hi[0] && lo[1] == hi[1] && lo[2] == hi[2]) {  // the box's one cell
    if ((++work & 4095u) == 0) poll();
    f(lo[0], lo[1], lo[2]);
    return;
  }
  // A triangle whose box lies within one cell on two axes touches every
  // cell of the row its box spans on the third: it is connected, so it
  // meets every slab of that axis its box meets, and on the other two axes
  // it lies inside the row's cells. The separating-axis test would list the
  // same cells.
  if (p.kind == PrimitiveKind::kTriangle && inner == 2) {
    for (int z = lo[2]; z <= hi[2]; ++z)
      for (int y = lo[1]; y <= hi[1]; ++y) {
        if ((++work & 4095u) == 0) poll();
        for (int x = lo[0]; x <= hi[0]; ++x) f(x, y, z);
      }
    return;
  }
  fill_cell_spans(info, eps, lo, hi, spans);
  if (p.kind == PrimitiveKind::kTriangle) return triangle_cells(p, lo, hi, spans, inner_axis, work, f, poll);
  if (p.kind == PrimitiveKind::kSphere) return sphere_cells(p, lo, hi, spans, work, f, poll);
  // Cone: the cell's bounding sphere must reach the capsule around the axis
  // segment with the larger radius (conservative; much tighter than the box
  // for long, thin, slanted cylinders).
  const double b0[3] = {p.data[0], p.data[1], p.data[2]};
  const double ax[3] = {double(p.data[4]) - b0[0], double(p.data[5]) - b0[1], double(p.data[6]) - b0[2]};
  const double len2 = ax[0] * ax[0] + ax[1] * ax[1] + ax[2] * ax[2];
  const double radius = std::max(std::fabs(double(p.data[3])), std::fabs(double(p.data[7])));
  for (int z = lo[2]; z <= hi[2]; ++z)
    for (int y = lo[1]; y <= hi[1]; ++y) {
      if ((++work & 4095u) == 0) poll();
      for (int x = lo[0]; x <= hi[0]; ++x) {
        const std::size_t i[3] = {std::size_t(x - lo[0]), std::size_t(y - lo[1]), std::size_t(z - lo[2])};
        const double c[3] = {spans.c[0][i[0]], spans.c[1][i[1]], spans.c[2][i[2]]};
        const double h[3] = {spans.h[0][i[0]], spans.h[1][i[1]], spans.h[2][i[2]]};
        double s = 0;
        if (len2 > 0)
          s = std::clamp(((c[0] - b0[0]) * ax[0] + (c[1] - b0[1]) * ax[1] + (c[2] - b0[2]) * ax[2]) / len2, 0.0, 1.0);
        double d2 = 0;
        for (int a = 0; a < 3; ++a) {
          const double q = b0[a] + s * ax[a] - c[a];
          d2 += q * q;
        }
        const double reach = radius + std::sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
        if (d2 <= reach * reach) f(x, y, z);
      }
    }
}

// The inflation of the cells of `info` for conservative membership: 1e-4 of
// a cell plus mag_eps (magnitude_eps).
void cell_inflation(const GridInfo& info, double mag_eps, double eps[3]) {
  for (int a = 0; a < 3; ++a) eps[a] = 1e-4 * info.cell_size[a] + mag_eps;
}

// Sets info.cell_size and inv_cell_size from bounds and res.
void set_cell_size(GridInfo& info) {
  for (int a = 0; a < 3; ++a) {
    info.cell_size[a] = (info.bounds.upper[a] - info.bounds.lower[a]) / float(info.res[a]);
    info.inv_cell_size[a] = 1.0f / info.cell_size[a];
  }
}

// 8 ulps of the larger of the top grid's box `b`'s coordinate magnitude and
// the tracing frame's (TopGridInfo::frame_magnitude): the rounding of a walk
// whose ray comes from within either cube (header comment).
double magnitude_eps(const Bounds3& b, float frame) {
  return 8.0 * std::numeric_limits<float>::epsilon() * std::max(coordinate_magnitude(b), frame);
}

// (cell, primitive) pairs of one run of primitives, in primitive order.
using CellPairs = std::vector<std::pair<std::uint32_t, std::uint32_t>>;

// Scratch of collect_pairs, kept across grids so that its capacity is reused:
// the pairs of each run of primitives and each run's for_each_overlapped_cell
// scratch.
struct PairRuns {
  std::vector<CellPairs> runs;
  std::vector<CellSpans> spans;
  std::vector<std::size_t> work;  // each run's cells tested (for_each_overlapped_cell's poll count)
};

// Primitives per run of collect_pairs below which it stays on the calling
// thread: a run must outweigh the cost of handing it to another thread.
constexpr std::size_t kPrimitivesPerRun = 1024;

// Threads the grid build may use: oneTBB's, as Embree's build does. One under
// ThreadSanitizer, which cannot see libtbb's (uninstrumented) synchronisation.
int build_threads() {
#if defined(__SANITIZE_THREAD__)
  return 1;
#else
  return std::max(1, tbb::this_task_arena::max_concurrency());
#endif
}

// The (cell, primitive) pairs of `count` primitives, the i-th being
// id_at(i) with bounds bounds_of(id), in the grid `info` whose cells are
// inflated by eps: out.runs in primitive order (one run, or with more
// hardware threads several runs of consecutive primitives made in parallel
// with oneTBB; the same pairs in the same order either way). poll() every
// 4096 primitives and as for_each_overlapped_cell says; a StopError it
// throws reaches the caller.
template <class IdAt, class BoundsOf, class Poll>
void collect_pairs(const GridInfo& info, const double eps[3], const Database& db, std::size_t count, IdAt&& id_at,
                   BoundsOf&& bounds_of, Poll&& poll, PairRuns& out) {
  const auto threads = std::size_t(build_threads());
  const std::size_t nruns = threads > 1 ? std::clamp<std::size_t>(count / kPrimitivesPerRun, 1, 4 * threads) : 1;
  out.runs.resize(nruns);
  if (out.spans.size() < nruns) out.spans.resize(nruns);
  out.work.assign(nruns, 0);
  auto run = [&](std::size_t k) {
    const std::size_t begin = count * k / nruns, end = count * (k + 1) / nruns;
    CellPairs& pairs = out.runs[k];
    pairs.clear();
    pairs.reserve((end - begin) * 2);
    for (std::size_t i = begin; i < end; ++i) {
      if ((i & 4095u) == 0) poll();
      const std::uint32_t id = id_at(i);
      for_each_overlapped_cell(info, eps, db.primitives[id], bounds_of(id), out.spans[k], out.work[k],
                               [&](int x, int y, int z) { pairs.emplace_back(info.cell_index(x, y, z), id); }, poll);
    }
  };
  if (nruns == 1) run(0);
  else tbb::parallel_for(std::size_t(0), nruns, run);
}

// The CSR cell lists of `ncells` cells from (cell, primitive) pairs, by a
// counting sort: cell c lists primitives[start[c] .. start[c + 1]) in the
// pairs' order, run after run (ascending ids when the pairs were made
// primitive by primitive).
void pairs_to_csr(std::span<const CellPairs> runs, std::uint32_t ncells, std::vector<std::uint32_t>& start,
                  std::vector<std::uint32_t>& primitives) {
  start.assign(std::size_t(ncells) + 1, 0);
  std::size_t total = 0;
  for (const CellPairs& pairs : runs) {
    total += pairs.size();
    for (const auto& pr : pairs) ++start[pr.first + 1];
  }
  for (std::uint32_t c = 0; c < ncells; ++c) start[c + 1] += start[c];
  primitives.resize(total);
  std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
  for (const CellPairs& pairs : runs)
    for (const auto& pr : pairs) primitives[fill[pr.first]++] = pr.second;
}

// The ids a grid lists, ascending: every primitive but the degenerate
// triangles (triangle_is_degenerate), which no ray hits, so that the walk
// need not check its would-be hits for them. Checked only when the database
// may hold some (not made with DatabaseParams::drop_degenerate).
std::vector<std::uint32_t> listed_ids(const Database& db) {
  std::vector<std::uint32_t> ids;
  ids.reserve(db.primitives.size());
  for (std::uint32_t i = 0; i < db.primitives.size(); ++i) {
    const Primitive& p = db.primitives[i];
    if (!db.degenerate_triangles_dropped && p.kind == PrimitiveKind::kTriangle &&
        triangle_is_degenerate(p.vertex(0), p.vertex(1), p.vertex(2)))
      continue;
    ids.push_back(i);
  }
  return ids;
}

Grid build_uniform_grid(const Database& db, const GridParams& params) {
  Grid grid;
  TopGridInfo& info = grid.info;
  const Bounds3 b = grid_bounds(db);
  info.bounds = b;
  info.frame_magnitude = params.frame_magnitude > 0 ? params.frame_magnitude : frame_magnitude(db);
  choose_grid_resolution(b, db.primitives.size(), params, info.res);
  set_cell_size(info);
  const std::uint32_t ncells = info.cell_count();
  double eps[3];
  cell_inflation(info, magnitude_eps(b, info.frame_magnitude), eps);

  // Pass 1 collects (cell, primitive) pairs; a counting sort makes the CSR.
  // Polled every 4096 primitives and every 4096 cells tested (one primitive
  // may span most of a large grid).
  auto poll_stop = [&] {
    if (stop_requested())
      throw_if_stopped(fmt::format("building the grid ({} primitives, {}x{}x{} cells)", db.primitives.size(),
                                   info.res[0], info.res[1], info.res[2]));
  };
  PairRuns pairs;
  const std::vector<std::uint32_t> ids = listed_ids(db);
  collect_pairs(
      info, eps, db, ids.size(), [&](std::size_t i) { return ids[i]; },
      [&](std::uint32_t id) { return db.primitives[id].bounds(); }, poll_stop, pairs);
  pairs_to_csr(pairs.runs, ncells, grid.cell_start, grid.cell_primitives);
  compute_empty_distance(grid, params.skip_empty);
  return grid;
}

}  // namespace

Bounds3 grid_bounds(const Database& db) { return pad_box(db.bounds); }

Bounds3 pad_box(Bounds3 b) {
  if (b.empty()) b = Bounds3{{-1, -1, -1}, {1, 1, 1}};
  // Pad: a flat scene still gets a cell of some thickness, and primitives on
  // the boundary lie strictly inside.
  const float emax = std::max(max_component(b.extent()), 1e-20f);
  const float mag = std::max(max_component(abs(b.lower)), max_component(abs(b.upper)));
  const float pad = std::max(1e-4f * emax, 16.0f * std::numeric_limits<float>::epsilon() * mag);
  b.lower -= Vec3{pad, pad, pad};
  b.upper += Vec3{pad, pad, pad};
  return b;
}

namespace {

// Per-axis resolution of an adaptive grid's box: the cube-root rule over
// the axes whose cells would be at least one cell thick. An axis on which
// the rule gives less than one cell gets one, and the cell budget is spread
// again over the others, so a thin axis gets one cell only when its
// cells would be thicker than the box is, never because it is thin next to
// the others (uniform's "flat axis" rule, choose_grid_resolution).
void choose_adaptive_resolution(const Bounds3& box, double cells, int max_resolution, int res[3]) {
  const Vec3 e = box.extent();
  bool live[3] = {e[0] > 0, e[1] > 0, e[2] > 0};
  res[0] = res[1] = res[2] = 1;
  cells = std::max(1.0, cells);
  for (int round = 0; round < 3; ++round) {
    double volume = 1.0;
    int n = 0;
    for (int a = 0; a < 3; ++a)
      if (live[a]) volume *= e[a], ++n;
    if (n == 0) return;
    const double per_unit = std::pow(cells / volume, 1.0 / n);
    bool dropped = false;
    for (int a = 0; a < 3; ++a)
      if (live[a] && double(e[a]) * per_unit < 1.0) live[a] = false, dropped = true;
    if (dropped) continue;
    for (int a = 0; a < 3; ++a)
      if (live[a]) res[a] = std::clamp(int(std::lround(double(e[a]) * per_unit)), 1, std::max(1, max_resolution));
    return;
  }
}

// make_sub_grid's estimate of the cells a surface crosses per cell area (a
// plane crosses |n_x| + |n_y| + |n_z| cells per cell area, 1.5 on average
// over directions).
constexpr double kSurfaceCellsPerArea = 1.5;

// x^(2/3) for x in [0, 1], within an ulp or two of std::cbrt(x * x): a
// first guess from the exponent bits, then Halley's iteration for the cube
// root (cubic convergence: 3% -> 1e-5 -> 1e-15 -> rounding). libm's cbrt
// was a fifth of the build of a scene of many partly covered spheres.
double two_thirds_power(double x) {
  const double y = x * x;
  if (!(y >= 1e-290)) return y > 0.0 ? std::cbrt(y) : 0.0;  // tiny (or NaN): rare, by the library
  double r = std::bit_cast<double>(0x2A9F7893782DA1CEull + std::bit_cast<std::uint64_t>(y) / 3);
  for (int i = 0; i < 3; ++i) {
    const double r3 = r * r * r;
    r *= (r3 + 2.0 * y) / (2.0 * r3 + y);
  }
  return r;
}

class AdaptiveBuilder {
 public:
  AdaptiveBuilder(const Database& db, const GridParams& params, Grid& grid)
      : db_(db), params_(params), grid_(grid) {
    bounds_.reserve(db.primitives.size());
    weights_.reserve(db.primitives.size());
    for (const Primitive& p : db.primitives) {
      bounds_.push_back(p.bounds());
      weights_.push_back(p.kind == PrimitiveKind::kTriangle ? params.triangle_weight
                         : p.kind == PrimitiveKind::kCone   ? params.cone_weight
                                                            : 1.0f);
      max_weight_ = std::max(max_weight_, weights_.back());
    }
  }

  // Builds the grid `info` over `prims` (ascending ids) at `level`, with
  // `large` (ascending ids) in the leaf after its cells (SubGrid); returns
  // its index in grid.sub_grids.
  std::uint32_t build(const GridInfo& info, std::span<const std::uint32_t> prims, std::uint32_t level,
                      std::span<const std::uint32_t> large = {}) {
    const auto index = std::uint32_t(grid_.sub_grids.size());
    const std::uint32_t ncells = info.cell_count();
    const auto first = std::uint32_t(grid_.cell_entries.size());
    const std::uint32_t nleaves = ncells + (large.empty() ? 0 : 1);
    grid_.sub_grids.push_back(SubGrid{info, first, level, !large.empty()});
    grid_.cell_entries.resize(std::size_t(first) + nleaves);
    double eps[3];
    cell_inflation(info, mag_eps_, eps);
    auto poll = [&] {
      if (stop_requested())
        throw_if_stopped(fmt::format("building the adaptive grid ({} primitives, {} grids so far)",
                                     db_.primitives.size(), grid_.sub_grids.size()));
    };
    // This grid's cell lists (CSR, by a counting sort of (cell, primitive)).
    collect_pairs(
        info, eps, db_, prims.size(), [&](std::size_t i) { return prims[i]; },
        [&](std::uint32_t id) -> const Bounds3& { return bounds_[id]; }, poll, pairs_);
    Grid local;
    static_cast<GridInfo&>(local.info) = info;
    pairs_to_csr(pairs_.runs, ncells, local.cell_start, local.cell_primitives);
    // A cell holding a sub-grid lists primitives, so it counts as non-empty.
    compute_empty_distance(local, params_.skip_empty);
    // Leaf first + c for every cell c, a placeholder (no list) where the
    // cell holds a sub-grid, then the large primitives' leaf; the
    // sub-grids are built after, so that this grid's leaves stay
    // contiguous (SubGrid).
    if (grid_.leaf_cells() != first) throw std::logic_error("build_grid: adaptive leaf numbering out of step");
    if (std::uint64_t(first) + nleaves >= kSubGridEntry)
      throw std::length_error("build_grid: more than 2^31 leaf cells in the adaptive grid");
    struct Child {
      std::uint32_t cell;
      GridInfo info;
      std::vector<std::uint32_t> small, large;  // the sub-grid's primitives; those beside it
    };
    // Which crowded cells get a sub-grid: each cell's answer depends on its
    // list alone, so they are found in parallel (oneTBB) and taken in cell
    // order.
    std::vector<Child> children;
    if (level < std::uint32_t(params_.max_depth))
      for (std::uint32_t c = 0; c < ncells; ++c)
        if (may_be_heavy(local.cell_start[c + 1] - local.cell_start[c])) children.push_back({c, {}, {}, {}});
    std::vector<char> refines(children.size(), 0);
    auto decide = [&](std::size_t i) {
      Child& child = children[i];
      const std::uint32_t b = local.cell_start[child.cell], e = local.cell_start[child.cell + 1];
      const std::span<const std::uint32_t> list = std::span(local.cell_primitives).subspan(b, e - b);
      const double weight = weighted_count(list);
      if (weight < params_.sub_grid_min) return;  // too light to be offered a sub-grid
      const bool split =
          split_large(cell_box(info, child.cell), list, kLargeShare * double(list.size()), child.small, child.large);
      bool refine = split ? make_sub_grid(info, child.cell, child.small, weighted_count(child.small), child.info)
                          : make_sub_grid(info, child.cell, list, weight, child.info);
      bool whole = !split;  // the sub-grid, if any, holds the whole list
      if (!refine && split) {  // the split did not pay: all in the sub-grid, if that does
        child.small.clear();
        child.large.clear();
        whole = true;
        refine = make_sub_grid(info, child.cell, list, weight, child.info);
      }
      if (refine && whole) child.small.assign(list.begin(), list.end());
      refines[i] = refine;
    };
    if (children.size() > 1 && build_threads() > 1)
      tbb::parallel_for(std::size_t(0), children.size(), decide);
    else
      for (std::size_t i = 0; i < children.size(); ++i) decide(i);
    std::size_t kept = 0;
    for (std::size_t i = 0; i < children.size(); ++i)
      if (refines[i]) {
        if (kept != i) children[kept] = std::move(children[i]);
        ++kept;
      }
    children.resize(kept);
    std::size_t next_child = 0;
    for (std::uint32_t c = 0; c < ncells; ++c) {
      const std::uint32_t b = local.cell_start[c], e = local.cell_start[c + 1];
      const bool refine = next_child < children.size() && children[next_child].cell == c;
      next_child += refine;
      if (!refine)
        grid_.cell_primitives.insert(grid_.cell_primitives.end(), local.cell_primitives.begin() + b,
                                     local.cell_primitives.begin() + e);
      grid_.cell_start.push_back(std::uint32_t(grid_.cell_primitives.size()));
      grid_.empty_distance.push_back(refine ? std::uint8_t(kSubGridMark) : local.empty_distance[c]);
      grid_.cell_entries[first + c] = first + c;
    }
    if (!large.empty()) {
      grid_.cell_primitives.insert(grid_.cell_primitives.end(), large.begin(), large.end());
      grid_.cell_start.push_back(std::uint32_t(grid_.cell_primitives.size()));
      grid_.empty_distance.push_back(0);
      grid_.cell_entries[first + ncells] = first + ncells;
    }
    for (const Child& ch : children) {
      const std::uint32_t child = build(ch.info, ch.small, level + 1, ch.large);
      grid_.cell_entries[first + ch.cell] = kSubGridEntry | child;
    }
    return index;
  }

  // Sets every level's cell margin: the top grid's (magnitude_eps), for
  // the top grid `top`. Called before build.
  void set_margin(const TopGridInfo& top) { mag_eps_ = magnitude_eps(top.bounds, top.frame_magnitude); }

  // The bounds of primitive `id` (computed once, in the constructor).
  const Bounds3& bounds(std::uint32_t id) const { return bounds_[id]; }

  // `ids`' primitives counted for the resolution rule: a triangle as
  // GridParams::triangle_weight, a cone as cone_weight, a sphere as 1.
  double weighted_count(std::span<const std::uint32_t> ids) const {
    double sum = 0;
    for (const std::uint32_t id : ids) sum += weights_[id];
    return sum;
  }

  // Whether a cell listing `count` primitives may weigh enough to be
  // offered a sub-grid (GridParams::sub_grid_min), its primitives all
  // weighing the most any does; the weighted sum itself is taken where the
  // cell's sub-grid is decided, in parallel.
  bool may_be_heavy(std::uint32_t count) const {
    return count > 0 && double(count) * max_weight_ >= params_.sub_grid_min;
  }

  // Splits `list`, the primitives of box `cell`, into those large in it
  // (header: kLargeSpan), in `large`, and the others, in `small`, when the
  // large ones are at most `max_large` and the others' box is at most half
  // the cell's on some axis: returns true. Else every primitive is small:
  // returns false and leaves both empty (the caller keeps `list`). Both
  // keep list order.
  bool split_large(const Bounds3& cell, std::span<const std::uint32_t> list, double max_large,
                   std::vector<std::uint32_t>& small, std::vector<std::uint32_t>& large) const {
    large.clear();
    small.clear();
    const Vec3 ce = cell.extent();
    Bounds3 small_box;
    for (const std::uint32_t id : list) {
      const Bounds3& pb = bounds_[id];
      int spanned = 0;
      for (int a = 0; a < 3; ++a) {
        const double lo = std::max(double(pb.lower[a]), double(cell.lower[a]));
        const double hi = std::min(double(pb.upper[a]), double(cell.upper[a]));
        spanned += hi - lo >= kLargeSpan * double(ce[a]);
      }
      if (spanned >= 2) {
        large.push_back(id);
        if (double(large.size()) > max_large) break;  // too many: no split, whatever the rest
      } else {
        small.push_back(id);
        small_box.extend(pb);
      }
    }
    bool gains = false;
    for (int a = 0; a < 3; ++a)
      gains |= double(std::min(small_box.upper[a], cell.upper[a])) - std::max(small_box.lower[a], cell.lower[a]) <=
               0.5 * double(ce[a]);
    if (large.empty() || small.empty() || double(large.size()) > max_large || !gains) {
      large.clear();
      small.clear();
      return false;
    }
    return true;
  }

 private:
  // The box of cell c of `info`.
  static Bounds3 cell_box(const GridInfo& info, std::uint32_t c) {
    const int x = int(c % std::uint32_t(info.res[0]));
    const int y = int(c / std::uint32_t(info.res[0]) % std::uint32_t(info.res[1]));
    const int z = int(c / (std::uint32_t(info.res[0]) * std::uint32_t(info.res[1])));
    return info.cell_bounds(x, y, z);
  }

  // The sub-grid cell c of `info` would hold over `list`, whose
  // weighted_count is `weight`, if one pays (header comment: the cost
  // model); false keeps the cell a leaf.
  bool make_sub_grid(const GridInfo& info, std::uint32_t c, std::span<const std::uint32_t> list, double weight,
                     GridInfo& sub) const {
    sub.bounds = tight_box(info, cell_box(info, c), list);
    const double n = double(list.size());
    choose_adaptive_resolution(sub.bounds, double(params_.density) * weight, kMaxSubGridResolution, sub.res);
    const double m = double(sub.cell_count());
    if (m < 2) return false;
    set_cell_size(sub);
    // Expected references: each primitive covers about prod_a min(res_a,
    // clipped extent_a / cell_a + 1) sub-cells, a sphere at most the cells
    // its surface inside the clipped box crosses (its whole surface
    // 4 pi r^2 times the box's share of the sphere's box to the power 2/3,
    // about 1.5 cells thick), not its whole box's.
    const double cell_area = std::pow(double(sub.cell_size[0]) * sub.cell_size[1] * sub.cell_size[2], 2.0 / 3.0);
    // A sub-cell lists at most kSubGridGain of the cell's primitives, and a
    // ray crossing the sub-grid (about cbrt(m) cells) meets at most
    // sub_grid_walk_share of the n references it would meet in the leaf.
    const double cbrt_m = std::cbrt(m);
    const auto pays = [&](double refs) {
      const double r = refs / m;
      return r <= kSubGridGain * n && cbrt_m * r <= params_.sub_grid_walk_share * n;
    };
    double refs = 0;
    std::size_t i = 0;
    for (const std::uint32_t id : list) {
      // The sum only grows: once a partial sum does not pay, the whole
      // will not (the same answer, without the rest of a long list).
      if (++i % 8 == 0 && !pays(refs)) return false;
      const Primitive& p = db_.primitives[id];
      const Bounds3& pb = bounds_[id];
      double k = 1, clipped[3];
      for (int a = 0; a < 3; ++a) {
        const double lo = std::max(double(pb.lower[a]), double(sub.bounds.lower[a]));
        const double hi = std::min(double(pb.upper[a]), double(sub.bounds.upper[a]));
        clipped[a] = std::max(0.0, hi - lo);
        k *= std::min(double(sub.res[a]), clipped[a] / sub.cell_size[a] + 1.0);
      }
      if (p.kind == PrimitiveKind::kSphere) {
        double share = 1;
        for (int a = 0; a < 3; ++a) {
          const double full = double(pb.upper[a]) - double(pb.lower[a]);
          if (full > 0) share *= clipped[a] / full;
        }
        const double r = double(p.radius());
        const double area = 4.0 * std::numbers::pi * r * r * (share < 1.0 ? two_thirds_power(share) : 1.0);
        k = std::min(k, kSurfaceCellsPerArea * area / cell_area + 1.0);
      }
      refs += k;
    }
    return pays(refs);
  }

  // The part of `cell` (a cell of `info`) that `list`'s primitives can
  // reach: their bounds' union grown by the cell inflation (they are
  // listed when they touch the inflated cell) and clipped to the cell. An
  // axis left thinner than twice that margin keeps the cell's extent, so
  // no sub-grid axis is degenerate.
  Bounds3 tight_box(const GridInfo& info, const Bounds3& cell, std::span<const std::uint32_t> list) const {
    Bounds3 reach;
    for (const std::uint32_t id : list) reach.extend(bounds_[id]);
    double eps[3];
    cell_inflation(info, mag_eps_, eps);
    Bounds3 box = cell;
    for (int a = 0; a < 3; ++a) {
      const double lo = std::max(double(cell.lower[a]), double(reach.lower[a]) - eps[a]);
      const double hi = std::min(double(cell.upper[a]), double(reach.upper[a]) + eps[a]);
      if (hi - lo < 2.0 * eps[a]) continue;
      // Rounded outwards, so the float box holds the double one.
      box.lower[a] = std::max(cell.lower[a], std::nextafter(float(lo), -std::numeric_limits<float>::infinity()));
      box.upper[a] = std::min(cell.upper[a], std::nextafter(float(hi), std::numeric_limits<float>::infinity()));
    }
    return box;
  }

  const Database& db_;
  const GridParams& params_;
  Grid& grid_;
  double mag_eps_ = 0;  // magnitude_eps of the top grid (set_margin)
  std::vector<Bounds3> bounds_;  // of each primitive, by id
  std::vector<float> weights_;   // of each primitive in the resolution rule, by id
  float max_weight_ = 0;         // the largest of weights_
  PairRuns pairs_;  // scratch of build: (cell, primitive) pairs
};

// The box the adaptive top grid covers within `box` (the scene's), the
// scene's few large primitives set aside (a floor, a wall), in `large`,
// ascending; `small` gets the others (both from `all`, ascending). Then again
// within that box, for scenes of nested scales (an object on its own ground,
// on a stadium floor), while `large` stays within kMaxTopLarge. With no
// large primitive, `box` and every primitive in `small`.
Bounds3 split_scene(const AdaptiveBuilder& builder, Bounds3 box, const std::vector<std::uint32_t>& all,
                    std::vector<std::uint32_t>& small, std::vector<std::uint32_t>& large) {
  std::vector<std::uint32_t> rest = all, found;
  large.clear();
  for (;;) {
    const double budget = std::min(double(kMaxTopLarge - large.size()), kLargeShare * double(rest.size()));
    if (budget < 1) break;
    builder.split_large(box, rest, budget, small, found);
    if (found.empty()) break;
    large.insert(large.end(), found.begin(), found.end());
    Bounds3 reach;
    for (const std::uint32_t id : small) reach.extend(builder.bounds(id));
    const Bounds3 padded = pad_box(reach);
    box = Bounds3{max(box.lower, padded.lower), min(box.upper, padded.upper)};
    rest.swap(small);
  }
  small.swap(rest);
  std::sort(large.begin(), large.end());
  return box;
}

// The slab of `ids` (PrimitiveSlab) across the normal of the largest
// triangle among them; with no triangle, across the axis of their boxes'
// least extent. Its ends hold every vertex (a triangle's) or box corner
// (another primitive's), so every point of the primitives by convexity, and
// are widened by 2^-40 of the points' magnitude for the dot products'
// rounding.
PrimitiveSlab primitive_slab(const Database& db, std::span<const std::uint32_t> ids) {
  PrimitiveSlab slab;
  slab.normal[2] = 0;
  double best = -1;
  Bounds3 box;
  for (const std::uint32_t id : ids) {
    const Primitive& p = db.primitives[id];
    box.extend(p.bounds());
    if (p.kind != PrimitiveKind::kTriangle) continue;
    const TriangleFrameDouble f = triangle_frame_double(p.vertex(0), p.vertex(1), p.vertex(2));
    const double* const n = f.n;
    const double area2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    if (area2 > best && std::isfinite(area2) && area2 > 0) {
      best = area2;
      const double len = std::sqrt(area2);
      for (int a = 0; a < 3; ++a) slab.normal[a] = n[a] / len;
    }
  }
  if (box.empty()) return PrimitiveSlab{};
  if (best < 0) {
    const Vec3 e = box.extent();
    slab.normal[e.x <= e.y && e.x <= e.z ? 0 : e.y <= e.z ? 1 : 2] = 1.0;
  }
  double lo = std::numeric_limits<double>::infinity(), hi = -lo, mag = 0;
  const auto take = [&](double x, double y, double z) {
    const double s = slab.normal[0] * x + slab.normal[1] * y + slab.normal[2] * z;
    lo = std::min(lo, s);
    hi = std::max(hi, s);
    mag = std::max(mag, std::fabs(x) + std::fabs(y) + std::fabs(z));
  };
  for (const std::uint32_t id : ids) {
    const Primitive& p = db.primitives[id];
    if (p.kind == PrimitiveKind::kTriangle) {
      for (int v = 0; v < 3; ++v) take(p.data[3 * v], p.data[3 * v + 1], p.data[3 * v + 2]);
    } else {
      const Bounds3 b = p.bounds();
      for (int c = 0; c < 8; ++c)
        take((c & 1) ? b.upper.x : b.lower.x, (c & 2) ? b.upper.y : b.lower.y, (c & 4) ? b.upper.z : b.lower.z);
    }
  }
  if (!std::isfinite(lo) || !std::isfinite(hi)) return PrimitiveSlab{};  // overflow: the whole space
  slab.lo = lo - 0x1p-40 * mag;
  slab.hi = hi + 0x1p-40 * mag;
  return slab;
}

Grid build_adaptive_grid(const Database& db, const GridParams& params) {
  Grid grid;
  TopGridInfo top;
  top.bounds = grid_bounds(db);
  std::vector<std::uint32_t> all = listed_ids(db), small, large;
  AdaptiveBuilder builder(db, params, grid);
  if (params.resolution[0] > 0 && params.resolution[1] > 0 && params.resolution[2] > 0) {
    for (int a = 0; a < 3; ++a) top.res[a] = std::min(params.resolution[a], params.max_resolution);
  } else {
    // The scene's few large primitives (a floor, a wall) beside the top
    // grid, which then covers only the others' box (header comment); then
    // again within that box, for scenes of nested scales (an object on its
    // own ground, on a stadium floor), while the leaf stays within
    // kMaxTopLarge.
    if (params.large_beside_top) top.bounds = split_scene(builder, top.bounds, all, small, large);
    choose_adaptive_resolution(top.bounds, double(params.top_density) * builder.weighted_count(large.empty() ? all : small),
                               params.max_resolution, top.res);
  }
  set_cell_size(top);
  if (!large.empty()) top.large_slab = primitive_slab(db, large);
  // The frame: the top grid's own box when it is the objects' box (the
  // large primitives split off, as frame_magnitude does), else computed.
  top.frame_magnitude = params.frame_magnitude > 0 ? params.frame_magnitude
                        : params.large_beside_top && params.resolution[0] <= 0 ? kFrameScale * coordinate_magnitude(top.bounds)
                                                                               : frame_magnitude(db);
  grid.info = top;
  grid.cell_start.push_back(0);
  builder.set_margin(top);
  builder.build(top, large.empty() ? std::span<const std::uint32_t>(all) : std::span<const std::uint32_t>(small), 0,
                large);
  grid.built_as = GridKind::kAdaptive;
  if (grid.sub_grids.size() == 1 && large.empty()) {  // nothing refined: the top grid alone, walked without the tables
    grid.sub_grids = {};
    grid.cell_entries = {};
  }
  return grid;
}

}  // namespace

float frame_magnitude(const Database& db) {
  Grid scratch;
  const GridParams params;
  const AdaptiveBuilder builder(db, params, scratch);
  std::vector<std::uint32_t> small, large;
  return kFrameScale * coordinate_magnitude(split_scene(builder, grid_bounds(db), listed_ids(db), small, large));
}

Grid build_grid(const Database& db, const GridParams& params) {
  return params.kind == GridKind::kAdaptive ? build_adaptive_grid(db, params) : build_uniform_grid(db, params);
}

void compute_empty_distance(Grid& grid, bool skip_empty) {
  const GridInfo& info = grid.info;
  const std::uint32_t ncells = info.cell_count();
  std::vector<std::uint8_t>& d = grid.empty_distance;
  d.resize(ncells);
  // Without a branch: which cells are empty follows the scene, and a
  // mispredicted branch per cell cost more than the pass's arithmetic.
  const std::uint8_t empty = skip_empty ? std::uint8_t(kMaxEmptyDistance) : 1;
  const std::uint32_t* const start = grid.cell_start.data();
  std::uint8_t* const out = d.data();
  for (std::uint32_t c = 0; c < ncells; ++c) out[c] = std::uint8_t(-std::uint8_t(start[c] == start[c + 1]) & empty);
  if (!skip_empty) return;
  // Two raster scans, forward then backward, each taking the minimum over
  // the 13 neighbours already scanned plus one: exact for the chessboard
  // metric. The scans run over a copy padded with one layer of cells at the
  // cap on every side (cells beyond the grid are empty, so they never lower
  // a distance), so the 13 neighbours are fixed offsets with no bounds test.
  const int rx = info.res[0], ry = info.res[1], rz = info.res[2];
  const std::ptrdiff_t px = rx + 2, py = ry + 2, pz = rz + 2;
  std::vector<std::uint8_t> p(std::size_t(px * py * pz), std::uint8_t(kMaxEmptyDistance));
  const auto padded = [&](int x, int y, int z) { return ((z + 1) * py + (y + 1)) * px + (x + 1); };
  for (int z = 0; z < rz; ++z)
    for (int y = 0; y < ry; ++y) std::copy_n(&d[info.cell_index(0, y, z)], rx, &p[std::size_t(padded(0, y, z))]);
  // The 13 neighbours before a cell in forward raster order: the previous
  // plane (dz = -1, all 9), the previous row (dy = -1, dz = 0, all 3), the
  // previous cell (dx = -1); the backward scan uses their negatives. The
  // previous plane is final before a plane is scanned, so the minimum of its
  // nine is taken for the whole plane at once, separably (over dx, then
  // over dy) in loops the compiler vectorises; the row and cell terms then
  // run cell by cell.
  const std::ptrdiff_t plane = px * py;
  std::vector<std::uint8_t> across(static_cast<std::size_t>(plane)), nine(static_cast<std::size_t>(plane));
  std::uint8_t* const base = p.data();
  for (int pass = 0; pass < 2; ++pass) {
    const std::ptrdiff_t s = pass == 0 ? 1 : -1;
    for (int zi = 0; zi < rz; ++zi) {
      const int z = s > 0 ? zi : rz - 1 - zi;
      std::uint8_t* const cur = base + (z + 1) * plane;
      const std::uint8_t* __restrict const prev_plane = cur - s * plane;
      // Raw restrict pointers: bytes may alias anything, and the loops
      // vectorise only when the compiler knows these do not.
      std::uint8_t* __restrict const t = across.data();
      std::uint8_t* __restrict const m = nine.data();
      for (std::ptrdiff_t i = 1; i < plane - 1; ++i)
        t[i] = std::min({prev_plane[i - 1], prev_plane[i], prev_plane[i + 1]});
      for (std::ptrdiff_t i = px; i < plane - px; ++i) m[i] = std::min({t[i - px], t[i], t[i + px]});
      for (int yi = 0; yi < ry; ++yi) {
        const int y = s > 0 ? yi : ry - 1 - yi;
        const std::ptrdiff_t row = (y + 1) * px + 1;  // cell (0, y) in the plane
        std::uint8_t* const c = cur + row;
        const std::uint8_t* const up = c - s * px;  // the row scanned before
        const std::uint8_t* const mr = m + row;
        // The terms from the previous plane and row first, for the whole
        // row at once (vectorised: the row does not alias them); a
        // minimum is at most the cap, 254, so adding one stays in a byte.
        {
          std::uint8_t* __restrict const cr = c;
          const std::uint8_t* __restrict const ur = up;
          const std::uint8_t* __restrict const mrr = mr;
          for (int x = 0; x < rx; ++x)
            cr[x] = std::min(cr[x], std::uint8_t(std::min({mrr[x], ur[x - 1], ur[x], ur[x + 1]}) + 1));
        }
        // Then the previous cell's, in scan order: min(c, before + 1).
        int before = kMaxEmptyDistance;  // the padding before the row
        for (int xi = 0; xi < rx; ++xi) {
          const int x = s > 0 ? xi : rx - 1 - xi;
          before = std::min(int(c[x]), before + 1);
          c[x] = std::uint8_t(before);
        }
      }
    }
  }
  for (int z = 0; z < rz; ++z)
    for (int y = 0; y < ry; ++y) std::copy_n(&p[std::size_t(padded(0, y, z))], rx, &d[info.cell_index(0, y, z)]);
}

}  // namespace raynode::core
