#include "core/validate.h"

#include <fmt/format.h>

#include <cmath>
#include <random>
#include <stdexcept>

#include "core/camera.h"
#include "core/direct_view.h"
#include "core/intersect.h"
#include "core/render.h"
#include "core/spawn.h"

namespace raynode::core {

ValidateCounts& ValidateCounts::operator+=(const ValidateCounts& o) {
  rays += o.rays;
  grid_hits += o.grid_hits;
  embree_hits += o.embree_hits;
  hit_vs_miss += o.hit_vs_miss;
  miss_vs_hit += o.miss_vs_hit;
  t_mismatch += o.t_mismatch;
  other_primitive += o.other_primitive;
  any_hit_mismatch += o.any_hit_mismatch;
  oracle_errors += o.oracle_errors;
  max_t_rel_error = std::max(max_t_rel_error, o.max_t_rel_error);
  return *this;
}

namespace {

// The referee for disagreements: the exact closest hit by brute force over
// every primitive, in double precision (triangles by the watertight test
// carried out in double; spheres and cones by their double-precision tests).
struct ReferenceHit {
  bool found = false;
  double t = 0.0;
};

// Relative barycentric margin within which a hit on a triangle's boundary may
// go either way in float arithmetic (a ray grazing a silhouette edge).
constexpr double kBoundaryMargin = 1e-5;

// margin > 0 shrinks the triangle (strict), < 0 grows it (lenient).
bool reference_triangle(const Ray& ray, const Primitive& p, double tmax, double margin, double& t_out) {
  const double o[3] = {ray.origin.x, ray.origin.y, ray.origin.z};
  const double d[3] = {ray.direction.x, ray.direction.y, ray.direction.z};
  int kz = 0;
  for (int a = 1; a < 3; ++a)
    if (std::fabs(d[a]) > std::fabs(d[kz])) kz = a;
  int kx = (kz + 1) % 3, ky = (kx + 1) % 3;
  if (d[kz] < 0) std::swap(kx, ky);
  const double sx = d[kx] / d[kz], sy = d[ky] / d[kz], sz = 1.0 / d[kz];
  double px[3], py[3], pz[3];
  double coord_error = 0;  // bound on the float test's rounding of px, py
  for (int i = 0; i < 3; ++i) {
    const double v[3] = {double(p.data[3 * i]) - o[0], double(p.data[3 * i + 1]) - o[1],
                         double(p.data[3 * i + 2]) - o[2]};
    px[i] = v[kx] - sx * v[kz];
    py[i] = v[ky] - sy * v[kz];
    pz[i] = sz * v[kz];
    coord_error = std::max(coord_error, std::fabs(v[kx]) + std::fabs(v[ky]) + 2 * std::max(std::fabs(sx), std::fabs(sy)) *
                                                                                std::fabs(v[kz]));
  }
  coord_error *= 0x1p-23;  // unit roundoff 2^-24, twice: the origin subtraction and the shear
  const double u = px[2] * py[1] - py[2] * px[1];
  const double v = px[0] * py[2] - py[0] * px[2];
  const double w = px[1] * py[0] - py[1] * px[0];
  const double det = u + v + w;
  if (det == 0) return false;
  if (margin != 0) {
    // Float barycentrics lose digits as the ray grazes the plane: scale the
    // margin by 1/|cos| of the ray/normal angle (capped at 1e4x, as for t).
    const TriangleFrameDouble f = triangle_frame_double(p.vertex(0), p.vertex(1), p.vertex(2));
    const double* const n = f.n;
    const double nl = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    const double dl = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    const double c = nl > 0 ? std::fabs(n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) / (nl * dl) : 1.0;
    margin /= std::max(c, 1e-4);
    // The float test computes px, py with absolute errors up to coord_error,
    // which grow with the distance from the origin: an edge function
    // px_j py_k - py_j px_k then errs by about coord_error x (|px_j| + |py_j|
    // + |px_k| + |py_k|), a barycentric by that / |det|. A small triangle
    // seen from far away thus has a wider band along its edges where float
    // may go either way than the relative margin alone allows.
    double edge_error = 0;
    for (int j = 0; j < 3; ++j) {
      const int k = (j + 1) % 3;
      edge_error = std::max(edge_error, std::fabs(px[j]) + std::fabs(py[j]) + std::fabs(px[k]) + std::fabs(py[k]));
    }
    margin += std::copysign(coord_error * edge_error / std::fabs(det), margin);
  }
  if (std::min({u / det, v / det, w / det}) < margin) return false;
  const double t = (u * pz[0] + v * pz[1] + w * pz[2]) / det;
  if (!(t > ray.tmin && t < tmax)) return false;
  if (margin > 0) {
    // The strict answer also leaves out a hit within the rounding of the
    // plane crossing in double (triangle_plane_t's bound, which the float
    // test applies where its own t is not good enough): an origin spawned
    // within rounding distance of a surface does not hit it.
    double tp = 0, err = 0;
    if (!triangle_plane_t(ray, p.vertex(0), p.vertex(1), p.vertex(2), tp, err) || !(tp > err)) return false;
    // Nor one within kNearOrigin float spacings of the origin, which the
    // float test may refuse as the surface the ray starts on.
    const double dmax = max_component(abs(ray.direction)), omax = max_component(abs(ray.origin));
    if (tp * dmax <= 2.0 * double(kNearOrigin) * omax) return false;
  }
  t_out = t;
  return true;
}

ReferenceHit reference_closest(const Database& db, const Ray& ray, double margin) {
  ReferenceHit best;
  double tmax = ray.tmax;
  for (const Primitive& p : db.primitives) {
    double t = 0;
    float tf = 0;
    bool hit = false;
    switch (p.kind) {
      case PrimitiveKind::kTriangle: hit = reference_triangle(ray, p, tmax, margin, t); break;
      case PrimitiveKind::kSphere:
        hit = intersect_sphere(ray, p.center(), p.radius(), float(tmax), tf);
        t = tf;
        break;
      case PrimitiveKind::kCone:
        hit = intersect_cone(ray, p.cone_base(), p.cone_base_radius(), p.cone_apex(), p.cone_apex_radius(),
                             float(tmax), tf);
        t = tf;
        break;
    }
    if (hit && t < tmax) {
      tmax = t;
      best = {true, t};
    }
  }
  return best;
}

class Checker {
 public:
  Checker(const Database& db, const Grid& grid, const EmbreeScene& embree, const ValidateParams& p,
          ValidateReport& report)
      : blocks_(p.pack_min > 0 ? build_cell_blocks(db, grid, p.pack_min, PackKinds::kTrianglesAndSpheres) : CellBlocks{}),
        view_(db, grid, p.pack_min > 0 ? &blocks_ : nullptr),
        embree_(embree),
        params_(p),
        report_(report) {
    diag_ = db.bounds.empty() ? 1.0f : length(db.bounds.extent());
  }

  /// Compares one closest-hit query; returns the grid's hit.
  Hit check(const char* set, const Ray& ray, ValidateCounts& c, bool also_any) {
    Hit g, e;
    const bool hg = intersect_closest(view_, ray, g, scratch_);
    const bool he = embree_.intersect_closest(ray, e);
    ++c.rays;
    c.grid_hits += hg;
    c.embree_hits += he;
    bool bad = hg != he;
    // A float hit distance is only as good as the ray/surface angle allows:
    // the error grows as 1/|cos| of the angle to the normal (grazing rays), so
    // the tolerance does too (capped at 1e4x).
    double slack = 1.0;
    if (hg || he) {
      const Primitive& p = view_.primitive(hg ? g.primitive : e.primitive);
      const Vec3 n = geometric_normal(p, ray.at(hg ? g.t : e.t));
      const double cosang = std::fabs(dot(n, ray.direction)) / (double(length(n)) * length(ray.direction));
      slack = 1.0 / std::max(cosang, 1e-4);
    }
    const double tol_rel = params_.t_rel * slack;
    if (hg && he) {
      const double tm = std::max(std::fabs(double(g.t)), std::fabs(double(e.t)));
      const double err = std::fabs(double(g.t) - double(e.t));
      if (err > tol_rel * tm + 1e-6 * diag_) {
        bad = true;
      } else {
        if (tm > 0) c.max_t_rel_error = std::max(c.max_t_rel_error, err / tm);
        if (g.primitive != e.primitive) ++c.other_primitive;
      }
    }
    bool any_bad = false;
    if (also_any) {
      const bool ag = intersect_any(view_, ray, scratch_);
      const bool ae = embree_.intersect_any(ray);
      // The any-hit answer must agree with the closest-hit answer of the
      // same structure and with the other structure.
      any_bad = ag != ae || ag != hg;
    }
    if (bad || any_bad) {
      // Disagreement: ask the double-precision referee. If the grid agrees
      // with it, Embree was wrong (its robust mode inflates triangles; its
      // float sphere test loses digits on small, distant spheres).
      // The referee answers twice: with triangles shrunk and grown by a
      // relative barycentric margin of 1e-5. Rays that close to an edge
      // (grazing a silhouette) may go either way in float; the grid is
      // right when its hit distance lies between the two answers.
      const double t_grid = hg ? double(g.t) : double(kInfinity);
      auto slack_at = [&](double t) { return std::isinf(t) ? 0.0 : tol_rel * std::fabs(t) + 1e-6 * diag_; };
      // The grid is right when its hit lies between the referee's strict and
      // lenient answers for the ray, or for the ray tested as the grid tests
      // it in its tracing frame (framed_ray: a ray from beyond the frame is
      // tested from its entry point, rounded to float, which moves its line
      // by up to half a float spacing of the frame's size; a ray grazing a
      // small sphere or cone that closely may go either way).
      const auto within = [&](const ReferenceHit& strict, const ReferenceHit& lenient) {
        const double t_near = lenient.found ? lenient.t : double(kInfinity);
        const double t_far = strict.found ? strict.t : double(kInfinity);
        return t_grid >= t_near - slack_at(t_near) && t_grid <= t_far + slack_at(t_far);
      };
      const Database& db = view_.database();
      bool grid_right = within(reference_closest(db, ray, kBoundaryMargin), reference_closest(db, ray, -kBoundaryMargin));
      const float frame = view_.grid_info().frame_magnitude;
      if (!grid_right && !origin_in_frame(frame, ray)) {
        const auto in_frame = [&](double margin) {
          Hit h;
          const bool found = closest_in_frame(frame, ray, h, [&](const Ray& piece, Hit& out) {
            const ReferenceHit r = reference_closest(db, piece, margin);
            out = Hit{};
            out.t = float(r.t);
            out.primitive = 0;
            return r.found;
          });
          return ReferenceHit{found, found ? double(h.t) : 0.0};
        };
        grid_right = within(in_frame(kBoundaryMargin), in_frame(-kBoundaryMargin));
      }
      if (grid_right && !(also_any && intersect_any(view_, ray, scratch_) != hg)) {
        ++c.oracle_errors;
        return g;
      }
      if (bad) {
        if (hg && !he) ++c.hit_vs_miss;
        else if (!hg && he) ++c.miss_vs_hit;
        else ++c.t_mismatch;
      }
      if (any_bad) ++c.any_hit_mismatch;
      if (report_.examples.size() < params_.max_examples) report_.examples.push_back({set, ray, g, e});
    }
    return g;
  }

  const DirectView& view() const { return view_; }
  TraversalStats stats() const { return scratch_.stats; }

 private:
  CellBlocks blocks_;  // before view_, which refers to it
  DirectView view_;
  const EmbreeScene& embree_;
  const ValidateParams& params_;
  ValidateReport& report_;
  TraversalScratch scratch_;
  float diag_ = 1.0f;
};

Vec3 random_unit(std::mt19937_64& rng) {
  std::normal_distribution<float> n(0.0f, 1.0f);
  for (;;) {
    const Vec3 v{n(rng), n(rng), n(rng)};
    const float l = length(v);
    if (l > 1e-6f) return v * (1.0f / l);
  }
}

Vec3 random_point_on(const Primitive& p, std::mt19937_64& rng) {
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  switch (p.kind) {
    case PrimitiveKind::kTriangle: {
      float a = u01(rng), b = u01(rng);
      if (a + b > 1.0f) {
        a = 1.0f - a;
        b = 1.0f - b;
      }
      return p.vertex(0) + (p.vertex(1) - p.vertex(0)) * a + (p.vertex(2) - p.vertex(0)) * b;
    }
    case PrimitiveKind::kSphere:
      return p.center() + random_unit(rng) * (0.999f * std::fabs(p.radius()));
    case PrimitiveKind::kCone: {
      const float s = u01(rng);
      return p.cone_base() + (p.cone_apex() - p.cone_base()) * s;  // on the axis: the ray crosses the surface
    }
  }
  return {};
}

}  // namespace

ValidateReport validate_grid(const Database& db, const Grid& grid, const EmbreeScene& embree,
                             const ValidateParams& params) {
  ValidateReport report;
  Checker chk(db, grid, embree, params, report);
  std::mt19937_64 rng(params.seed);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);

  struct Origin {
    Ray ray;
    Hit hit;
  };
  std::vector<Origin> hits;  // grid hits to spawn secondary rays from

  const View view = render_view(db);
  const Camera cam(view, params.width, params.height);
  for (int y = 0; y < params.height; ++y)
    for (int x = 0; x < params.width; ++x) {
      const Ray r = cam.ray_through(float(x) + 0.5f, float(y) + 0.5f);
      const Hit h = chk.check("primary", r, report.primary, false);
      if (h.found() && (hits.size() < 200000 || u01(rng) < 0.1f)) hits.push_back({r, h});
    }

  if (!db.primitives.empty()) {
    Bounds3 box = db.bounds;
    const Vec3 grow = box.extent() * 0.25f;
    box.lower -= grow;
    box.upper += grow;
    std::uniform_int_distribution<std::size_t> pick(0, db.primitives.size() - 1);
    for (std::size_t i = 0; i < params.random_rays; ++i) {
      const Vec3 o{box.lower.x + u01(rng) * (box.upper.x - box.lower.x),
                   box.lower.y + u01(rng) * (box.upper.y - box.lower.y),
                   box.lower.z + u01(rng) * (box.upper.z - box.lower.z)};
      Vec3 d = random_unit(rng);
      if (i % 2) {
        const Vec3 target = random_point_on(db.primitives[pick(rng)], rng);
        const Vec3 to = target - o;
        if (length(to) > 1e-6f * length(box.extent())) d = normalize(to);
      }
      const Ray r{o, d, 0.0f, kInfinity};
      const Hit h = chk.check("random", r, report.random, true);
      if (h.found() && hits.size() < 400000) hits.push_back({r, h});
    }
  }

  // Secondary rays start where the tracer starts them (spawn.h): from the
  // grid's hit point with its error bound, offset to the side they leave
  // towards. Both structures get the same ray.
  for (const Origin& o : hits) {
    const Primitive& p = db.primitives[o.hit.primitive];
    const HitPoint hp = hit_point(p, o.ray, o.hit);
    const Vec3 n = hp.normal;
    if (!(dot(n, n) > 0.0f)) continue;
    const Vec3 d = normalize_any(o.ray.direction);
    // Mirror reflection, leaving on the side the ray came from.
    const Vec3 nf = dot(n, d) < 0.0f ? n : -n;
    const Vec3 refl = d - n * (2.0f * dot(d, n));
    chk.check("reflected", Ray{offset_ray_origin(hp, nf), refl, 0.0f, kInfinity}, report.reflected, true);
    // A random direction, leaving on its own side (as a refracted or shadow ray may).
    const Vec3 rd = random_unit(rng);
    const Vec3 side = dot(n, rd) >= 0.0f ? n : -n;
    chk.check("scattered", Ray{offset_ray_origin(hp, side), rd, 0.0f, kInfinity}, report.scattered, true);
  }
  report.secondary = report.reflected;
  report.secondary += report.scattered;

  report.total = report.primary;
  report.total += report.random;
  report.total += report.secondary;
  report.grid_stats = chk.stats();
  return report;
}

}  // namespace raynode::core
