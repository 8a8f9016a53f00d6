#include "dataflow/region.h"

#include <fmt/core.h>

#include <algorithm>
#include <limits>
#include <stdexcept>

#include "core/camera.h"

namespace raynode::dataflow {

CameraFrame CameraFrame::of(const core::View& view) {
  const core::Vec3 dir = view.at - view.from;
  if (!(core::dot(dir, dir) > 0.0f)) throw std::invalid_argument("view 'from' and 'at' are the same point");
  CameraFrame f;
  f.origin = view.from;
  f.w = core::normalize_any(dir);  // as core::Camera
  if (!core::up_is_usable(f.w, view.up)) throw std::invalid_argument("view 'up' is parallel to the viewing direction");
  const core::Vec3 right = core::cross(f.w, view.up);  // as core::Camera
  f.u = core::is_finite(right) ? core::normalize_any(right) : core::normalize(core::cross(f.w, core::normalize_any(view.up)));
  f.v = core::cross(f.u, f.w);
  return f;
}

std::uint32_t RegionMap::locate(float x, float y, float dx, float dy) const {
  std::int32_t i = 0;
  for (;;) {
    const KdNode& n = tree[std::size_t(i)];
    if (n.axis < 0) return std::uint32_t(n.child[0]);
    const float c = n.axis == 0 ? x : y;
    const float d = n.axis == 0 ? dx : dy;
    const bool upper = c > n.cut || (c == n.cut && d >= 0.0f);
    i = n.child[upper ? 1 : 0];
  }
}

float RegionMap::exit_region(std::uint32_t region, const ScreenRay& r, float t_enter, std::uint32_t& next) const {
  const ScreenRect& b = rects[region];
  constexpr float inf = core::kInfinity;
  float tx = inf, ty = inf;
  if (r.dx > 0.0f && b.x1 < inf) tx = (b.x1 - r.x0) / r.dx;
  else if (r.dx < 0.0f && b.x0 > -inf) tx = (b.x0 - r.x0) / r.dx;
  if (r.dy > 0.0f && b.y1 < inf) ty = (b.y1 - r.y0) / r.dy;
  else if (r.dy < 0.0f && b.y0 > -inf) ty = (b.y0 - r.y0) / r.dy;
  float t = tx < ty ? tx : ty;
  if (!(t < inf)) return inf;
  if (t < t_enter) t = t_enter;
  // The crossing point: exactly on the exited face(s); the other coordinate
  // kept within this region's face so that the next region borders it.
  float x, y;
  if (tx <= ty) x = r.dx > 0.0f ? b.x1 : b.x0;
  else x = std::clamp(r.x0 + t * r.dx, b.x0, b.x1);
  if (ty <= tx) y = r.dy > 0.0f ? b.y1 : b.y0;
  else y = std::clamp(r.y0 + t * r.dy, b.y0, b.y1);
  next = locate(x, y, r.dx, r.dy);
  return t;
}

ScreenRect screen_extent(const CameraFrame& frame, const core::Bounds3& bounds) {
  core::Bounds3 b = bounds;
  if (b.empty()) b = core::Bounds3{{-1, -1, -1}, {1, 1, 1}};
  ScreenRect e{core::kInfinity, core::kInfinity, -core::kInfinity, -core::kInfinity};
  for (int i = 0; i < 8; ++i) {
    const core::Vec3 p{(i & 1) ? b.upper.x : b.lower.x, (i & 2) ? b.upper.y : b.lower.y,
                       (i & 4) ? b.upper.z : b.lower.z};
    const float x = frame.x(p), y = frame.y(p);
    e.x0 = std::min(e.x0, x), e.x1 = std::max(e.x1, x);
    e.y0 = std::min(e.y0, y), e.y1 = std::max(e.y1, y);
  }
  const float size = std::max({e.x1 - e.x0, e.y1 - e.y0, 1e-20f});
  const float mag = std::max({std::fabs(e.x0), std::fabs(e.x1), std::fabs(e.y0), std::fabs(e.y1)});
  const float pad = std::max(1e-4f * size, 64.0f * std::numeric_limits<float>::epsilon() * mag);
  e.x0 -= pad, e.y0 -= pad, e.x1 += pad, e.y1 += pad;
  return e;
}

double CostGrid::total() const {
  double t = 0;
  for (double c : cost) t += c;
  return t;
}

namespace {

/// A part being cut, in cell units of the cost grid ([0, nx] x [0, ny]).
struct Part {
  double g0[2], g1[2];      ///< lower and upper corner, cell units
  bool open_lo[2], open_hi[2];  ///< side on the extent's border: infinite in the ownership rectangle
};

struct Builder {
  const CostGrid& cost;
  Partition& out;

  float to_screen(int axis, double g) const {
    const ScreenRect& e = cost.extent;
    const double lo = e.lo(axis), hi = e.hi(axis);
    const int n = axis == 0 ? cost.nx : cost.ny;
    if (g <= 0) return float(lo);
    if (g >= n) return float(hi);
    return float(lo + (hi - lo) * g / n);
  }

  /// Cost per unit length along `axis` of each cell slice of the part.
  double marginal(const Part& p, int axis, std::vector<double>& per_cell) const {
    const int n = axis == 0 ? cost.nx : cost.ny;
    const int other = 1 - axis;
    per_cell.assign(std::size_t(n), 0.0);
    const int o0 = std::max(0, int(std::floor(p.g0[other]))), o1 = std::min(other == 0 ? cost.nx : cost.ny,
                                                                          int(std::ceil(p.g1[other])));
    double total = 0;
    for (int i = 0; i < n; ++i) {
      const double len = std::min(double(i + 1), p.g1[axis]) - std::max(double(i), p.g0[axis]);
      if (len <= 0) continue;
      double s = 0;
      for (int j = o0; j < o1; ++j) {
        const double cov = std::min(double(j + 1), p.g1[other]) - std::max(double(j), p.g0[other]);
        if (cov <= 0) continue;
        const std::size_t idx = axis == 0 ? std::size_t(j) * cost.nx + i : std::size_t(i) * cost.nx + j;
        s += cost.cost[idx] * cov;
      }
      per_cell[std::size_t(i)] = s;
      total += s * len;
    }
    return total;
  }

  std::int32_t split(const Part& p, std::uint32_t n, int depth, std::uint32_t& next_region) {
    const std::int32_t index = std::int32_t(out.tree.size());
    out.tree.emplace_back();
    if (n == 1) {
      const std::uint32_t r = next_region++;
      out.tree[std::size_t(index)].child[0] = std::int32_t(r);
      ScreenRect own{to_screen(0, p.g0[0]), to_screen(1, p.g0[1]), to_screen(0, p.g1[0]), to_screen(1, p.g1[1])};
      out.finite[r] = own;
      if (p.open_lo[0]) own.x0 = -core::kInfinity;
      if (p.open_lo[1]) own.y0 = -core::kInfinity;
      if (p.open_hi[0]) own.x1 = core::kInfinity;
      if (p.open_hi[1]) own.y1 = core::kInfinity;
      out.rects[r] = own;
      return index;
    }
    const int axis = depth % 2;
    const std::uint32_t na = n / 2;
    const double frac = double(na) / double(n);
    std::vector<double> per_cell;
    const double total = marginal(p, axis, per_cell);
    double cut = p.g0[axis] + frac * (p.g1[axis] - p.g0[axis]);
    if (total > 0) {
      double need = frac * total;
      cut = p.g1[axis];
      const int cells = axis == 0 ? cost.nx : cost.ny;
      for (int i = 0; i < cells; ++i) {
        const double lo = std::max(double(i), p.g0[axis]), hi = std::min(double(i + 1), p.g1[axis]);
        if (hi <= lo) continue;
        const double c = per_cell[std::size_t(i)];
        const double part = c * (hi - lo);
        if (c > 0 && part >= need) {
          cut = lo + need / c;
          break;
        }
        need -= part;
      }
      cut = std::clamp(cut, p.g0[axis], p.g1[axis]);
    }
    Part lower = p, upper = p;
    lower.g1[axis] = upper.g0[axis] = cut;
    lower.open_hi[axis] = upper.open_lo[axis] = false;
    out.tree[std::size_t(index)].axis = axis;
    out.tree[std::size_t(index)].cut = to_screen(axis, cut);
    const std::int32_t a = split(lower, na, depth + 1, next_region);
    const std::int32_t b = split(upper, n - na, depth + 1, next_region);
    out.tree[std::size_t(index)].child[0] = a;
    out.tree[std::size_t(index)].child[1] = b;
    return index;
  }
};

}  // namespace

Partition make_partition(const CameraFrame& frame, const CostGrid& cost, std::uint32_t regions) {
  if (regions == 0) throw std::invalid_argument("make_partition: the region count must be >= 1");
  if (cost.nx < 1 || cost.ny < 1 || cost.cost.size() != std::size_t(cost.nx) * cost.ny)
    throw std::invalid_argument(fmt::format("make_partition: a {}x{} cost grid with {} cells", cost.nx, cost.ny,
                                            cost.cost.size()));
  Partition p;
  p.frame = frame;
  p.extent = cost.extent;
  p.rects.resize(regions);
  p.finite.resize(regions);
  p.tree.reserve(2 * std::size_t(regions));
  Part root{{0, 0}, {double(cost.nx), double(cost.ny)}, {true, true}, {true, true}};
  std::uint32_t next = 0;
  Builder{cost, p}.split(root, regions, 0, next);
  return p;
}

double cost_in(const CostGrid& cost, const ScreenRect& rect) {
  const ScreenRect& e = cost.extent;
  const double sx = (double(e.x1) - e.x0) / cost.nx, sy = (double(e.y1) - e.y0) / cost.ny;
  double total = 0;
  for (int j = 0; j < cost.ny; ++j) {
    const double cy0 = e.y0 + j * sy, cy1 = e.y0 + (j + 1) * sy;
    const double oy = std::min(cy1, double(rect.y1)) - std::max(cy0, double(rect.y0));
    if (oy <= 0) continue;
    for (int i = 0; i < cost.nx; ++i) {
      const double cx0 = e.x0 + i * sx, cx1 = e.x0 + (i + 1) * sx;
      const double ox = std::min(cx1, double(rect.x1)) - std::max(cx0, double(rect.x0));
      if (ox <= 0) continue;
      total += cost.cost[std::size_t(j) * cost.nx + i] * (ox / sx) * (oy / sy);
    }
  }
  return total;
}

}  // namespace raynode::dataflow
