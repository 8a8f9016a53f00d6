#include "core/database.h"

#include <fmt/format.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "core/intersect.h"
#include "core/stop.h"

namespace raynode::core {

Bounds3 Primitive::bounds() const {
  Bounds3 b;
  switch (kind) {
    case PrimitiveKind::kTriangle:
      b.extend(vertex(0));
      b.extend(vertex(1));
      b.extend(vertex(2));
      break;
    case PrimitiveKind::kSphere: {
      const float r = std::fabs(radius());
      b.extend(center() - Vec3{r, r, r});
      b.extend(center() + Vec3{r, r, r});
      break;
    }
    case PrimitiveKind::kCone: {
      const float rb = std::fabs(cone_base_radius()), ra = std::fabs(cone_apex_radius());
      b.extend(cone_base() - Vec3{rb, rb, rb});
      b.extend(cone_base() + Vec3{rb, rb, rb});
      b.extend(cone_apex() - Vec3{ra, ra, ra});
      b.extend(cone_apex() + Vec3{ra, ra, ra});
      break;
    }
  }
  return b;
}

DatabaseCounts Database::counts() const {
  DatabaseCounts c;
  for (const Primitive& p : primitives) {
    switch (p.kind) {
      case PrimitiveKind::kTriangle: ++c.triangles; break;
      case PrimitiveKind::kSphere: ++c.spheres; break;
      case PrimitiveKind::kCone: ++c.cones; break;
    }
  }
  c.vertex_normal_sets = vertex_normals.size();
  return c;
}

std::size_t Database::bytes() const {
  return primitives.size() * sizeof(Primitive) + vertex_normals.size() * sizeof(TriangleNormals) +
         materials.size() * sizeof(Material);
}

namespace {

// Twice the signed area of the 2D triangle (a, b, c), in double.
double orient2d(const double* a, const double* b, const double* c) {
  return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

// The tracer's own criterion (intersect.h), so that a database made with
// drop_degenerate holds no triangle the tracer would refuse.
bool triangle_area_is_zero(const Vec3& a, const Vec3& b, const Vec3& c) { return triangle_is_degenerate(a, b, c); }

/// Projects the polygon onto the plane its Newell normal is most nearly
/// perpendicular to, turned so that it runs counter-clockwise: p = x0 y0 x1
/// y1 ... (2n doubles).
void project_polygon(const Vec3* verts, std::uint32_t n, std::vector<double>& p) {
  double nrm[3] = {0, 0, 0};
  for (std::uint32_t i = 0; i < n; ++i) {
    const Vec3& a = verts[i];
    const Vec3& b = verts[(i + 1) % n];
    nrm[0] += (double(a.y) - b.y) * (double(a.z) + b.z);
    nrm[1] += (double(a.z) - b.z) * (double(a.x) + b.x);
    nrm[2] += (double(a.x) - b.x) * (double(a.y) + b.y);
  }
  int drop = 0;
  if (std::fabs(nrm[1]) > std::fabs(nrm[drop])) drop = 1;
  if (std::fabs(nrm[2]) > std::fabs(nrm[drop])) drop = 2;
  const int ax = (drop + 1) % 3, ay = (drop + 2) % 3;
  const double sign = nrm[drop] >= 0 ? 1.0 : -1.0;
  p.resize(2 * std::size_t(n));
  for (std::uint32_t i = 0; i < n; ++i) {
    p[2 * i] = verts[i][ax];
    p[2 * i + 1] = sign * verts[i][ay];
  }
}

/// The balanced split: the triangle (0, n/2, n-1), then the same within
/// each of the two chains it cuts off, down to single triangles. n-2
/// triangles in the polygon's orientation whose sizes halve level by level,
/// so that a grid lists each in few cells (a fan's long slivers each cross
/// most of the grid). Any polygon, any shape: whether the triangles cover it
/// is for covers_once() to say.
template <class Emit>
void balanced_split(std::uint32_t n, Emit&& emit) {
  struct Chain {
    std::uint32_t first, last;  // vertices first..last, closed by the chord last -> first
  };
  std::vector<Chain> todo{{0, n - 1}};  // depth first: at most ~log2(n) pending per level
  while (!todo.empty()) {
    const Chain c = todo.back();
    todo.pop_back();
    if (c.last - c.first < 2) continue;
    const std::uint32_t mid = c.first + (c.last - c.first) / 2;
    emit(c.first, mid, c.last);
    todo.push_back({mid, c.last});
    todo.push_back({c.first, mid});
  }
}

/// The fan around the last vertex, in the order ear clipping gives a convex
/// polygon: it clips the corner at vertex 0, then 1, ... (each time with the
/// last vertex), the last triangle starting at n-3.
template <class Emit>
void fan_split(std::uint32_t n, Emit&& emit) {
  for (std::uint32_t k = 0; k + 3 < n; ++k) emit(n - 1, k, k + 1);
  emit(n - 3, n - 2, n - 1);
}

/// True when the triangles `split` makes cover the projected polygon once.
/// Any split into n-2 triangles along diagonals has the polygon's signed
/// area as the sum of theirs (exactly, in exact arithmetic) and covers each
/// point as often as the outline winds round it; the triangles cover the
/// polygon once when none turns over, i.e. when their absolute areas sum to
/// no more, up to kFanAreaTolerance of it (room for rounding of the stored
/// coordinates). O(n).
template <class Split>
bool covers_once(const std::vector<double>& p, std::uint32_t n, Split&& split) {
  double sum = 0, abs_sum = 0;
  split(n, [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    const double t = orient2d(&p[2 * std::size_t(a)], &p[2 * std::size_t(b)], &p[2 * std::size_t(c)]);
    sum += t;
    abs_sum += std::fabs(t);
  });
  return sum > 0 && abs_sum <= sum * (1 + kFanAreaTolerance);
}

const auto kBalanced = [](std::uint32_t n, auto&& emit) { balanced_split(n, emit); };
const auto kFan = [](std::uint32_t n, auto&& emit) { fan_split(n, emit); };

/// Eberly's ear clipping over the projected polygon, O(n^2) (see
/// triangulate_polygon). Polls the stop request about every 2^20 vertex tests.
template <class Emit>
void ear_clip(const std::vector<double>& p, std::uint32_t n, Emit&& emit) {
  std::vector<std::uint32_t> idx(n);
  for (std::uint32_t i = 0; i < n; ++i) idx[i] = i;
  // An ear is a convex corner whose triangle contains no other remaining
  // vertex. Collinear corners are clipped as (dropped) zero-area ears.
  std::size_t guard = 0;
  std::size_t i = 0;
  std::size_t work = 0;  // vertex tests since the last stop poll
  while (idx.size() > 3) {
    const std::size_t m = idx.size();
    work += m;
    if (work >= (std::size_t{1} << 20)) {
      work = 0;
      if (stop_requested()) throw_if_stopped(fmt::format("triangulating a polygon of {} vertices", n));
    }
    const std::uint32_t ia = idx[(i + m - 1) % m], ib = idx[i % m], ic = idx[(i + 1) % m];
    const double* a = &p[2 * ia];
    const double* b = &p[2 * ib];
    const double* c = &p[2 * ic];
    bool ear = orient2d(a, b, c) >= 0;
    if (ear) {
      for (std::size_t k = 0; k < m && ear; ++k) {
        const std::uint32_t j = idx[k];
        if (j == ia || j == ib || j == ic) continue;
        const double* q = &p[2 * j];
        // Inside or on the boundary of the ear (strictly excluding the ear's corners).
        if (orient2d(a, b, q) >= 0 && orient2d(b, c, q) >= 0 && orient2d(c, a, q) >= 0) {
          // A vertex coinciding with a corner (polygons that touch themselves) does not block.
          if (!((q[0] == a[0] && q[1] == a[1]) || (q[0] == b[0] && q[1] == b[1]) ||
                (q[0] == c[0] && q[1] == c[1])))
            ear = false;
        }
      }
    }
    if (ear) {
      emit(ia, ib, ic);
      idx.erase(idx.begin() + static_cast<std::ptrdiff_t>(i % m));
      guard = 0;
      if (i >= idx.size()) i = 0;
      continue;
    }
    ++i;
    if (++guard > idx.size()) {
      // No ear found (self-intersecting or numerically tricky input): fall
      // back to a fan over what remains so that no area is lost.
      for (std::size_t k = 1; k + 1 < idx.size(); ++k) emit(idx[0], idx[k], idx[k + 1]);
      return;
    }
  }
  emit(idx[0], idx[1], idx[2]);
}

}  // namespace

bool splits_in_linear_time(const Vec3* verts, std::uint32_t n) {
  if (n <= 3) return true;
  std::vector<double> p;
  project_polygon(verts, n, p);
  return covers_once(p, n, kBalanced) || covers_once(p, n, kFan);
}

void triangulate_polygon(const Vec3* verts, std::uint32_t n, std::vector<std::uint32_t>& out,
                         bool drop_degenerate) {
  if (n < 3) return;
  auto emit = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    if (drop_degenerate && triangle_area_is_zero(verts[a], verts[b], verts[c])) return;
    out.push_back(a);
    out.push_back(b);
    out.push_back(c);
  };
  if (n == 3) {
    emit(0, 1, 2);
    return;
  }
  std::vector<double> p;
  project_polygon(verts, n, p);
  if (n > kEarClippingVertices) {
    // O(n): the balanced split when it covers the polygon (every convex
    // one), else the fan when it does (one star-shaped from its last vertex).
    const std::string doing = fmt::format("triangulating a polygon of {} vertices", n);
    std::uint32_t made = 0;
    auto emit_polled = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
      if ((made++ & 4095u) == 0) throw_if_stopped(doing);
      emit(a, b, c);
    };
    if (covers_once(p, n, kBalanced)) return balanced_split(n, emit_polled);
    if (covers_once(p, n, kFan)) return fan_split(n, emit_polled);
    if (n > kMaxConcavePolygonVertices) {
      throw std::invalid_argument(fmt::format(
          "a polygon of {} vertices is not convex; a concave polygon may have at most {} vertices (ear clipping "
          "takes time quadratic in the count), unless it is star-shaped from its last vertex; split it into "
          "smaller polygons",
          n, kMaxConcavePolygonVertices));
    }
  }
  ear_clip(p, n, emit);
}

Database make_database(const Scene& scene, const DatabaseParams& params) {
  Database db;
  db.materials = scene.materials;
  if (db.materials.empty()) db.materials.push_back(Material{});
  db.lights = scene.lights;
  db.view = scene.view;
  db.has_view = scene.has_view;
  db.background = scene.background;
  db.shape_count = scene.shapes.size();
  db.degenerate_triangles_dropped = params.drop_degenerate;
  db.primitives.reserve(scene.shapes.size());

  std::vector<std::uint32_t> tris;
  std::size_t work = 0;  // shapes and polygon vertices since the last stop poll
  for (std::size_t si = 0; si < scene.shapes.size(); ++si) {
    const Shape& s = scene.shapes[si];
    work += 1 + ((s.kind == ShapeKind::kPolygon || s.kind == ShapeKind::kPatch) ? s.count : 0);
    if (work >= 4096) {
      work = 0;
      throw_if_stopped("making the database (triangulating polygons)");
    }
    Primitive prim;
    prim.material = s.material;
    prim.shape = static_cast<std::uint32_t>(si);
    switch (s.kind) {
      case ShapeKind::kPolygon:
      case ShapeKind::kPatch: {
        const Vec3* v = &scene.vertices[s.first];
        tris.clear();
        try {
          triangulate_polygon(v, s.count, tris, params.drop_degenerate);
        } catch (const std::invalid_argument& e) {
          throw std::invalid_argument(fmt::format("shape {} (in file order): {}", si, e.what()));
        }
        db.dropped_degenerate_triangles += (s.count - 2) - tris.size() / 3;
        prim.kind = PrimitiveKind::kTriangle;
        for (std::size_t t = 0; t < tris.size(); t += 3) {
          for (int k = 0; k < 3; ++k) {
            const Vec3& p = v[tris[t + k]];
            prim.data[3 * k] = p.x;
            prim.data[3 * k + 1] = p.y;
            prim.data[3 * k + 2] = p.z;
          }
          if (s.kind == ShapeKind::kPatch) {
            TriangleNormals tn;
            for (int k = 0; k < 3; ++k) tn.n[k] = scene.normals[s.first_normal + tris[t + k]];
            prim.normals = static_cast<std::uint32_t>(db.vertex_normals.size());
            db.vertex_normals.push_back(tn);
          }
          db.primitives.push_back(prim);
        }
        break;
      }
      case ShapeKind::kSphere: {
        const Sphere& sp = scene.spheres[s.first];
        prim.kind = PrimitiveKind::kSphere;
        prim.data[0] = sp.center.x;
        prim.data[1] = sp.center.y;
        prim.data[2] = sp.center.z;
        prim.data[3] = sp.radius;
        db.primitives.push_back(prim);
        break;
      }
      case ShapeKind::kCone: {
        const Cone& c = scene.cones[s.first];
        prim.kind = PrimitiveKind::kCone;
        const float d[8] = {c.base.x, c.base.y, c.base.z, c.base_radius,
                            c.apex.x, c.apex.y, c.apex.z, c.apex_radius};
        for (int k = 0; k < 8; ++k) prim.data[k] = d[k];
        db.primitives.push_back(prim);
        break;
      }
    }
    if (db.primitives.size() >= kNoPrimitive)
      throw std::invalid_argument("scene has more than 2^32-2 primitives");
  }
  for (const Primitive& p : db.primitives) db.bounds.extend(p.bounds());
  return db;
}

}  // namespace raynode::core
