#include "core/grid.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "core/stop.h"

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

Grid build_grid(const Database& db, const GridParams& params) {
  Grid grid;
  GridInfo& info = grid.info;
  Bounds3 b = db.bounds;
  if (b.empty()) b = Bounds3{{-1, -1, -1}, {1, 1, 1}};
  // Pad: a flat scene still gets a cell of some thickness, and primitives on
  // the boundary lie strictly inside.
  const float emax = std::max(max_component(b.extent()), 1e-20f);
  const float mag = std::max(max_component(abs(b.lower)), max_component(abs(b.upper)));
  const float pad = std::max(1e-4f * emax, 16.0f * std::numeric_limits<float>::epsilon() * mag);
  b.lower -= Vec3{pad, pad, pad};
  b.upper += Vec3{pad, pad, pad};
  info.bounds = b;
  choose_grid_resolution(b, db.primitives.size(), params, info.res);
  for (int a = 0; a < 3; ++a) {
    info.cell_size[a] = (b.upper[a] - b.lower[a]) / float(info.res[a]);
    info.inv_cell_size[a] = 1.0f / info.cell_size[a];
  }
  const std::uint32_t ncells = info.cell_count();

  // Inflation of each cell for conservative membership.
  const double mag_eps = 8.0 * std::numeric_limits<float>::epsilon() *
                         std::max(max_component(abs(b.lower)), max_component(abs(b.upper)));
  double eps[3];
  for (int a = 0; a < 3; ++a) eps[a] = 1e-4 * info.cell_size[a] + mag_eps;

  auto cell_range = [&](const Bounds3& pb, int lo[3], int hi[3]) {
    for (int a = 0; a < 3; ++a) {
      const double l = (double(pb.lower[a]) - eps[a] - b.lower[a]) * info.inv_cell_size[a];
      const double h = (double(pb.upper[a]) + eps[a] - b.lower[a]) * info.inv_cell_size[a];
      lo[a] = clamped_floor(l, info.res[a]);
      hi[a] = clamped_floor(h, info.res[a]);
    }
  };
  auto cell_box = [&](int x, int y, int z, double c[3], double h[3]) {
    const int idx[3] = {x, y, z};
    for (int a = 0; a < 3; ++a) {
      const double lo = double(b.lower[a]) + double(idx[a]) * info.cell_size[a];
      const double hi = double(b.lower[a]) + double(idx[a] + 1) * info.cell_size[a];
      c[a] = 0.5 * (lo + hi);
      h[a] = 0.5 * (hi - lo) + eps[a];
    }
  };

  // Pass 1 collects (cell, primitive) pairs; a counting sort makes the CSR.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  pairs.reserve(db.primitives.size() * 2);
  // Polled every 4096 primitives and every 4096 cells tested (one primitive
  // may span most of a large grid).
  std::size_t work = 0;
  auto poll_stop = [&] {
    if (stop_requested())
      throw_if_stopped(fmt::format("building the grid ({} primitives, {}x{}x{} cells)", db.primitives.size(),
                                   info.res[0], info.res[1], info.res[2]));
  };
  for (std::uint32_t pi = 0; pi < db.primitives.size(); ++pi) {
    if ((pi & 4095u) == 0) poll_stop();
    const Primitive& p = db.primitives[pi];
    int lo[3], hi[3];
    cell_range(p.bounds(), lo, hi);
    const bool single = lo[0] == hi[0] && lo[1] == hi[1] && lo[2] == hi[2];
    double tv[3][3];
    if (p.kind == PrimitiveKind::kTriangle)
      for (int i = 0; i < 3; ++i)
        for (int a = 0; a < 3; ++a) tv[i][a] = p.data[3 * i + a];
    for (int z = lo[2]; z <= hi[2]; ++z)
      for (int y = lo[1]; y <= hi[1]; ++y)
        for (int x = lo[0]; x <= hi[0]; ++x) {
          if ((++work & 4095u) == 0) poll_stop();
          bool in = true;
          if (!single) {
            double c[3], h[3];
            cell_box(x, y, z, c, h);
            if (p.kind == PrimitiveKind::kTriangle) {
              in = tri_box_sat(tv, c, h);
            } else if (p.kind == PrimitiveKind::kSphere) {
              // Arvo: squared distance from the centre to the box <= r^2, and
              // the box not entirely inside the sphere (the surface must cross it).
              const double r = std::fabs(double(p.radius()));
              double dmin = 0, dmax = 0;
              for (int a = 0; a < 3; ++a) {
                const double q = double(p.data[a]);
                const double lo_a = c[a] - h[a], hi_a = c[a] + h[a];
                const double dl = q - lo_a, dh = hi_a - q;
                if (q < lo_a) dmin += dl * dl;
                else if (q > hi_a) dmin += dh * dh;
                const double far = std::max(std::fabs(dl), std::fabs(dh));
                dmax += far * far;
              }
              in = dmin <= r * r && dmax >= r * r;
            } else {
              // Cone: the cell's bounding sphere must reach the capsule
              // around the axis segment with the larger radius (conservative;
              // much tighter than the box for long, thin, slanted cylinders).
              const double b0[3] = {p.data[0], p.data[1], p.data[2]};
              const double ax[3] = {double(p.data[4]) - b0[0], double(p.data[5]) - b0[1],
                                    double(p.data[6]) - b0[2]};
              const double len2 = ax[0] * ax[0] + ax[1] * ax[1] + ax[2] * ax[2];
              double s = 0;
              if (len2 > 0)
                s = std::clamp(((c[0] - b0[0]) * ax[0] + (c[1] - b0[1]) * ax[1] + (c[2] - b0[2]) * ax[2]) / len2,
                               0.0, 1.0);
              double d2 = 0;
              for (int a = 0; a < 3; ++a) {
                const double q = b0[a] + s * ax[a] - c[a];
                d2 += q * q;
              }
              const double reach = std::max(std::fabs(double(p.data[3])), std::fabs(double(p.data[7]))) +
                                   std::sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
              in = d2 <= reach * reach;
            }
          }
          if (in) pairs.emplace_back(info.cell_index(x, y, z), pi);
        }
  }
  grid.cell_start.assign(std::size_t(ncells) + 1, 0);
  for (const auto& pr : pairs) ++grid.cell_start[pr.first + 1];
  for (std::uint32_t c = 0; c < ncells; ++c) grid.cell_start[c + 1] += grid.cell_start[c];
  grid.cell_primitives.resize(pairs.size());
  std::vector<std::uint32_t> fill(grid.cell_start.begin(), grid.cell_start.end() - 1);
  for (const auto& pr : pairs) grid.cell_primitives[fill[pr.first]++] = pr.second;
  compute_empty_distance(grid, params.skip_empty);
  return grid;
}

void compute_empty_distance(Grid& grid, bool skip_empty) {
  const GridInfo& info = grid.info;
  const std::uint32_t ncells = info.cell_count();
  std::vector<std::uint8_t>& d = grid.empty_distance;
  d.assign(ncells, 0);
  for (std::uint32_t c = 0; c < ncells; ++c)
    if (grid.cell_start[c] == grid.cell_start[c + 1]) d[c] = skip_empty ? std::uint8_t(kMaxEmptyDistance) : 1;
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
    for (int y = 0; y < ry; ++y)
      for (int x = 0; x < rx; ++x) p[std::size_t(padded(x, y, z))] = d[info.cell_index(x, y, z)];
  // The 13 neighbours before a cell in forward raster order: the previous
  // plane (dz = -1, all 9), the previous row (dy = -1, dz = 0, all 3), the
  // previous cell (dx = -1). The backward scan uses their negatives.
  std::ptrdiff_t offsets[13];
  int k = 0;
  for (int dz = -1; dz <= 0; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx)
        if (!(dz == 0 && (dy > 0 || (dy == 0 && dx >= 0)))) offsets[k++] = (dz * py + dy) * px + dx;
  std::uint8_t* const base = p.data();
  for (int pass = 0; pass < 2; ++pass) {
    const std::ptrdiff_t s = pass == 0 ? 1 : -1;
    for (int zi = 0; zi < rz; ++zi) {
      const int z = s > 0 ? zi : rz - 1 - zi;
      for (int yi = 0; yi < ry; ++yi) {
        const int y = s > 0 ? yi : ry - 1 - yi;
        std::uint8_t* cell = base + padded(s > 0 ? 0 : rx - 1, y, z);
        for (int xi = 0; xi < rx; ++xi, cell += s) {
          if (*cell <= 1) continue;  // non-empty, or next to a non-empty cell already
          int best = *cell;
          for (const std::ptrdiff_t o : offsets) best = std::min(best, cell[s * o] + 1);
          *cell = std::uint8_t(best);
        }
      }
    }
  }
  for (int z = 0; z < rz; ++z)
    for (int y = 0; y < ry; ++y)
      for (int x = 0; x < rx; ++x) d[info.cell_index(x, y, z)] = p[std::size_t(padded(x, y, z))];
}

}  // namespace raynode::core
