// Whitted shading of NFF materials (the SPD shading model): one ray in, one
// colour out, recursing into reflected and refracted rays.
//
// Place in the data flow: camera ray (render.h) -> trace_ray -> closest hit
// through a database view (traverse.h) -> shade: ambient + per-light shadow
// ray, Lambert and Phong terms + Ks * reflected ray + T * refracted ray.
// Written against the database-view concept of traverse.h, so every mode
// (sequential, shared, replicated, svm, dataflow) shades with this code.
//
// The model (docs/nff.md, "Shading model"; Whitted, "An
// Improved Illumination Model for Shaded Display", CACM 1980):
//   I = I_a*Kd*C + sum_lights vis * I_l * Lc * (Kd*C*max(0,N.L) + Ks*max(0,R.V)^Shine)
//       + Ks*I_reflect + T*I_refract
// Policies (documented choices where NFF is silent):
// * Intensities: each light and the ambient term get sqrt(L)/(2L), L = number
//   of lights (SPD's suggestion); with no lights the ambient gets 1/2.
// * Ambient coefficient Ka = Kd (NFF has no Ka).
// * Highlight weight = Ks (docs/nff.md, "Shading model"); skipped when Ks = 0 or when
//   Shine >= 100000 (the "no highlight" marker). The highlight is white times
//   the light colour.
// * Two-sided shading: the normal is face-forwarded towards the incoming ray
//   for every primitive, which renders the teapot double-sided (the lid gap
//   shows the inside) and is identical to one-sided shading for every surface
//   seen from its front. Entering/exiting for refraction uses the sign of
//   N.D with the unflipped geometric normal.
// * `pp` triangles: shading normal = barycentric interpolation of the vertex
//   normals (Hit::u weights v1, Hit::v weights v2), flipped with the
//   geometric normal.
// * Secondary-ray origins: the hit point carries a bound on its rounding
//   error (spawn.h, hit_point); shadow and reflected rays start just past
//   that bound on the side the ray came from, refracted rays on the side
//   they leave towards (offset_ray_origin; pbrt-v4's error-bounded spawn).
//   No absolute epsilon: the offset is a few float spacings of the
//   primitive's coordinates, whatever the scene's scale or position.
// * Shadow rays are not cast when the shading normal faces away from the
//   light (N.L <= 0). Depth: the eye ray is level 1; no secondary ray is
//   spawned from level max_depth. Min-weight pruning (Hall & Greenberg,
//   "A Testbed for Realistic Image Synthesis", IEEE CG&A 1983): a child ray
//   whose weight (product of Ks / T factors along the path) is below
//   min_weight is not cast.
#pragma once

#include <cmath>
#include <cstdint>
#include <span>

#include "core/database.h"
#include "core/intersect.h"
#include "core/math.h"
#include "core/spawn.h"
#include "core/stop.h"
#include "core/traverse.h"

namespace raynode::core {

/// Shine values at or above this are SPD's "no highlight" marker.
inline constexpr float kNoHighlightShine = 100000.0f;

/// Rays cast, by kind.
struct RayCounts {
  std::uint64_t primary = 0;
  std::uint64_t shadow = 0;
  std::uint64_t reflected = 0;
  std::uint64_t refracted = 0;  ///< includes total-internal-reflection rays spawned for T
  /// Of `refracted`, the rays that were totally internally reflected (Snell
  /// had no solution); a sub-count, not part of total().
  std::uint64_t refracted_tir = 0;
  std::uint64_t total() const { return primary + shadow + reflected + refracted; }
  RayCounts& operator+=(const RayCounts& o) {
    primary += o.primary;
    shadow += o.shadow;
    reflected += o.reflected;
    refracted += o.refracted;
    refracted_tir += o.refracted_tir;
    return *this;
  }
};

/// Rays not cast, by reason.
struct SkipCounts {
  std::uint64_t reflection_ks0 = 0;     ///< hit with Ks = 0: no reflected ray
  std::uint64_t refraction_t0 = 0;      ///< hit with T = 0: no refracted ray
  std::uint64_t shadow_backfacing = 0;  ///< light behind the shading normal
  std::uint64_t highlight_marker = 0;   ///< Shine >= 100000 with Ks > 0: no highlight
  std::uint64_t depth_limit = 0;        ///< reflected/refracted ray not cast at max depth
  std::uint64_t min_weight = 0;         ///< reflected/refracted ray below min_weight
  SkipCounts& operator+=(const SkipCounts& o) {
    reflection_ks0 += o.reflection_ks0;
    refraction_t0 += o.refraction_t0;
    shadow_backfacing += o.shadow_backfacing;
    highlight_marker += o.highlight_marker;
    depth_limit += o.depth_limit;
    min_weight += o.min_weight;
    return *this;
  }
};

/// All counters of a render (or of one thread's share of it).
struct RenderStats {
  RayCounts rays;
  SkipCounts skipped;
  TraversalStats traversal;
  RenderStats& operator+=(const RenderStats& o) {
    rays += o.rays;
    skipped += o.skipped;
    traversal += o.traversal;
    return *this;
  }
};

/// Which lights a hit casts shadow rays to. kFacing (the default): only
/// those the shading normal faces, since a light behind the surface adds
/// nothing. kAll: every light, as the paper's tracer counted them (its
/// Table 2 ray counts for Tetra9 and Tetra10 are ours plus the lights
/// behind the surface; docs/results.md); a ray to a light behind adds
/// nothing either, so the image is the same and only the work differs.
enum class ShadowRays : std::uint8_t { kFacing, kAll };
/// "facing", "all".
inline const char* shadow_rays_name(ShadowRays s) { return s == ShadowRays::kAll ? "all" : "facing"; }

/// What shading needs besides the database view: the O(1) scene metadata
/// every node replicates (lights, background), intensities and recursion
/// limits. Materials and `pp` vertex normals are per-object data and come
/// through the view (view.material(id), view.vertex_normals(id)), so a paged
/// or regional view can hold them where its primitives are. `lights` refers
/// to (does not own) an array that must outlive the context. Read-only, so
/// it may be shared by any number of threads.
struct ShadingContext {
  std::span<const Light> lights;
  Vec3 background;
  float light_intensity = 0.5f;    ///< per light, sqrt(L)/(2L)
  float ambient_intensity = 0.5f;  ///< sqrt(L)/(2L), 1/2 with no lights
  int max_depth = 5;               ///< ray levels, eye ray = 1
  float min_weight = 0.0f;         ///< Hall & Greenberg pruning threshold (0 = off)
  ShadowRays shadow_rays = ShadowRays::kFacing;
};

/// Builds the context for these lights and background with SPD's
/// intensities. max_depth >= 1.
inline ShadingContext make_shading_context(std::span<const Light> lights, const Vec3& background, int max_depth = 5,
                                           float min_weight = 0.0f, ShadowRays shadow_rays = ShadowRays::kFacing) {
  ShadingContext c;
  c.lights = lights;
  c.background = background;
  const std::size_t n = lights.size();
  const float i = n == 0 ? 0.5f : float(std::sqrt(double(n)) / (2.0 * double(n)));
  c.light_intensity = i;
  c.ambient_intensity = i;
  c.max_depth = max_depth;
  c.min_weight = min_weight;
  c.shadow_rays = shadow_rays;
  return c;
}

/// The context for `db`'s lights and background (db must outlive it).
inline ShadingContext make_shading_context(const Database& db, int max_depth = 5, float min_weight = 0.0f,
                                           ShadowRays shadow_rays = ShadowRays::kFacing) {
  return make_shading_context(std::span<const Light>(db.lights), db.background, max_depth, min_weight, shadow_rays);
}

/// Refraction direction by Snell's law (Whitted 1980; vector form as in
/// Heckbert's "Writing a Ray Tracer", 1989): unit incident direction `d`,
/// unit normal `n` on the side `d` comes from (dot(d, n) <= 0), `eta` =
/// n_from / n_to. Writes the (unit) transmitted direction and returns true,
/// or returns false on total internal reflection (eta * sin(theta_i) > 1),
/// leaving `out` untouched.
inline bool refract(const Vec3& d, const Vec3& n, float eta, Vec3& out) {
  const float cosi = -dot(d, n);
  const float k = 1.0f - eta * eta * (1.0f - cosi * cosi);
  if (k < 0.0f) return false;
  out = d * eta + n * (eta * cosi - std::sqrt(k));
  return true;
}

/// The local frame of a hit, as shading sees it.
struct SurfaceFrame {
  Vec3 p;            ///< hit point on the surface, world units (hit_point)
  Vec3 d;            ///< unit ray direction
  Vec3 nf;           ///< unit geometric normal, face-forwarded towards the ray's origin side
  Vec3 ns;           ///< unit shading normal (interpolated for `pp` triangles), flipped like nf
  bool front = true; ///< the ray arrives at the front side (dot(unflipped normal, d) < 0)
  Vec3 above;        ///< origin of rays leaving on nf's side (shadow, reflected), world units
  Vec3 below;        ///< origin of rays leaving on the other side (refracted)
  /// The hit triangle's id when the hit is on a triangle whose plane has a
  /// normal there, else kNoPrimitive (spheres, cones: curved).
  std::uint32_t triangle = kNoPrimitive;

  /// intersect_closest's origin_triangle for `ray`, a ray spawned here:
  /// `triangle` when `ray` starts at `above` or `below` and its direction
  /// goes clearly to that side of the plane (the cosine to nf beyond
  /// 2^-10, far above nf's rounding): offset_ray_origin put the origin
  /// strictly on that side, so the plane lies behind it and the triangle
  /// cannot be met. kNoPrimitive otherwise (a shadow ray to a light behind
  /// the surface crosses it).
  std::uint32_t leaving(const Ray& ray) const {
    const float side = ray.origin == above ? 1.0f : ray.origin == below ? -1.0f : 0.0f;
    return side * dot(ray.direction, nf) > 0x1p-10f * length(ray.direction) ? triangle : kNoPrimitive;
  }
};

/// Frame of the closest hit `hit` of `ray` (hit.found()). `prim` is the hit
/// primitive as the view returned it; `pp` vertex normals come from the view.
/// The point and the two spawn origins come from spawn.h (hit_point,
/// offset_ray_origin), the same in every mode.
template <class View>
SurfaceFrame surface_frame(const View& view, const Primitive& prim, const Ray& ray, const Hit& hit) {
  SurfaceFrame f;
  f.d = normalize_any(ray.direction);
  const HitPoint hp = hit_point(prim, ray, hit);
  f.p = hp.p;
  // Geometric normal: raw (for entering/exiting) and face-forwarded.
  Vec3 ng = hp.normal;
  if (!(dot(ng, ng) > 0.0f)) ng = -f.d;
  f.front = dot(ng, f.d) < 0.0f;
  f.nf = f.front ? ng : -ng;
  f.above = offset_ray_origin(hp, f.nf);
  f.below = offset_ray_origin(hp, -f.nf);
  if (prim.kind == PrimitiveKind::kTriangle && dot(hp.normal, hp.normal) > 0.0f) f.triangle = hit.primitive;
  // Shading normal, flipped together with the geometric one.
  f.ns = f.nf;
  if (prim.kind == PrimitiveKind::kTriangle && prim.normals != kNoNormals) {
    const TriangleNormals& vn = view.vertex_normals(prim.normals);
    const Vec3 n = vn.n[0] * (1.0f - hit.u - hit.v) + vn.n[1] * hit.u + vn.n[2] * hit.v;
    const float len = length(n);
    if (len > 0.0f && std::isfinite(len)) f.ns = f.front ? n * (1.0f / len) : n * (-1.0f / len);
  }
  return f;
}

/// What the first hit of an eye ray leaves for the AOVs (render.h).
struct FirstHit {
  float t = kInfinity;       ///< distance along the (unit) ray, world units; +inf on a miss
  Vec3 normal;               ///< unit shading normal, face-forwarded towards the eye; (0,0,0) on a miss
  std::int64_t shape = -1;   ///< Primitive::shape (NFF shape index in file order) of the hit; -1 on a miss
};

/// Per-thread mutable state of shading: traversal scratch and counters.
struct ShadingScratch {
  TraversalScratch traversal;
  RenderStats stats;
};

/// The ambient term of material `m`, unweighted: Ka * C * I_a with Ka = Kd.
inline Vec3 ambient_term(const ShadingContext& ctx, const Material& m) {
  return m.color * (m.kd * ctx.ambient_intensity);
}

/// A secondary ray that shading asks for (shade_hit).
enum class ChildKind : std::uint8_t { kReflected, kRefracted };

/// Whitted's terms at one hit (the model above), for every mode's tracer:
/// trace_ray here casts the rays it asks for at once; dataflow sends them on
/// as messages. `m` is the hit primitive's material, `f` its frame (from
/// surface_frame), `depth` the level of the ray that hit (eye ray = 1) and
/// `weight` its contribution factor; counts rays and skips into `st`.
/// The ambient term (ambient_term) is the caller's; shade_hit calls, in this
/// order:
/// - `shadow(ray, light_term, highlight_skipped)` for each light the shading
///   normal faces (every light under ShadowRays::kAll, a light behind
///   giving a black term): `ray` runs from the hit to the light (tmax 1), and
///   `light_term()` is the light's Lambert + Phong term, to add when nothing
///   blocks `ray`; `highlight_skipped` says Ks > 0 but the highlight was off
///   (counted by the caller, as skipped.highlight_marker, when unblocked);
/// - `child(kind, ray, w)` for the reflected and the refracted ray, when
///   depth and weight allow (w = weight x Ks or T); its colour is to be
///   scaled by Ks (reflected) or T (refracted).
template <class Shadow, class Child>
void shade_hit(const ShadingContext& ctx, const Material& m, const SurfaceFrame& f, int depth, float weight,
               RenderStats& st, Shadow&& shadow, Child&& child) {
  const Vec3& d = f.d;
  const Vec3& nf = f.nf;
  const Vec3& ns = f.ns;
  const Vec3& above = f.above;  // on the side the ray came from
  const Vec3 v = -d;

  const bool highlight = m.ks > 0.0f && m.shine < kNoHighlightShine;
  for (const Light& light : ctx.lights) {
    const Vec3 to_light = light.position - above;
    const float dist = length(to_light);
    if (!(dist > 0.0f)) continue;
    const Vec3 l = to_light * (1.0f / dist);
    const float ndotl = dot(ns, l);
    const bool facing = !(ndotl <= 0.0f);  // only a light clearly behind (not a NaN term) is skipped
    if (!facing && ctx.shadow_rays == ShadowRays::kFacing) {
      ++st.skipped.shadow_backfacing;
      continue;
    }
    ++st.rays.shadow;
    auto light_term = [&] {
      if (!facing) return Vec3{};  // ShadowRays::kAll: a light behind the surface adds nothing
      Vec3 c = m.color * (m.kd * ndotl);
      if (highlight) {
        const Vec3 r = ns * (2.0f * ndotl) - l;
        const float rv = dot(r, v);
        if (rv > 0.0f) c += Vec3{1.0f, 1.0f, 1.0f} * (m.ks * std::pow(rv, m.shine));
      }
      return c * light.color * ctx.light_intensity;
    };
    shadow(Ray{above, to_light, 0.0f, 1.0f}, light_term, facing && !highlight && m.ks > 0.0f);
  }

  // May a child ray of weight w be cast? Counts the skip reason otherwise.
  auto may_spawn = [&](float w) {
    if (depth >= ctx.max_depth) {
      ++st.skipped.depth_limit;
      return false;
    }
    if (w < ctx.min_weight) {
      ++st.skipped.min_weight;
      return false;
    }
    return true;
  };
  // Mirror direction about ns; falls back to the geometric normal when the
  // interpolated normal would send it below the surface.
  auto reflect_dir = [&]() {
    Vec3 r = d - ns * (2.0f * dot(d, ns));
    if (dot(r, nf) <= 0.0f) r = d - nf * (2.0f * dot(d, nf));
    return r;
  };

  if (m.ks > 0.0f) {
    const float w = weight * m.ks;
    if (may_spawn(w)) {
      const Ray r{above, reflect_dir(), 0.0f, kInfinity};
      if (is_valid_ray(r)) {
        ++st.rays.reflected;
        child(ChildKind::kReflected, r, w);
      }
    }
  } else {
    ++st.skipped.reflection_ks0;
  }

  if (m.transmittance > 0.0f) {
    const float w = weight * m.transmittance;
    if (may_spawn(w)) {
      const float ior = m.ior > 0.0f ? m.ior : 1.0f;
      const float eta = f.front ? 1.0f / ior : ior;  // n_from / n_to
      Vec3 dir;
      const bool tir = !refract(d, ns, eta, dir);
      if (tir) dir = reflect_dir();  // total internal reflection
      const Ray r{dot(dir, nf) > 0.0f ? above : f.below, dir, 0.0f, kInfinity};
      if (is_valid_ray(r)) {
        ++st.rays.refracted;
        if (tir) ++st.rays.refracted_tir;
        child(ChildKind::kRefracted, r, w);
      }
    }
  } else {
    ++st.skipped.refraction_t0;
  }
}

/// Colour seen along `ray` (level `depth`, 1 = eye ray; `weight` = its
/// contribution factor to the pixel). Counts the rays it casts (not `ray`
/// itself: the caller counts that by kind). `first_hit`, when non-null,
/// receives the distance, shading normal and shape index of the first hit
/// (FirstHit's defaults on a miss). The database view may be any view of
/// traverse.h, or one with its own intersect_closest / intersect_any
/// overloads (embree_view.h). `origin_triangle`: the triangle `ray` leaves
/// (SurfaceFrame::leaving), or kNoPrimitive. Owner thread of `scratch` only.
template <class View>
Vec3 trace_ray(const View& view, const ShadingContext& ctx, const Ray& ray, int depth, float weight,
               ShadingScratch& scratch, FirstHit* first_hit = nullptr,
               std::uint32_t origin_triangle = kNoPrimitive) {
  // --timeout reaches inside a pixel, however deep its ray tree (core/stop.h).
  throw_if_stopped("tracing rays");
  Hit hit;
  if (!intersect_closest(view, ray, hit, scratch.traversal, origin_triangle)) {
    if (first_hit) *first_hit = FirstHit{};
    return ctx.background;
  }
  // A copy: a paged view may evict the page behind a returned reference on
  // its next access (vertex normals, shadow rays), see traverse.h.
  const Primitive prim = view.primitive(hit.primitive);
  const Material& m = view.material(prim.material);
  const SurfaceFrame f = surface_frame(view, prim, ray, hit);
  if (first_hit) *first_hit = FirstHit{hit.t, f.ns, std::int64_t(prim.shape)};
  Vec3 color = ambient_term(ctx, m);
  shade_hit(
      ctx, m, f, depth, weight, scratch.stats,
      [&](const Ray& shadow, auto&& light_term, bool highlight_skipped) {
        if (intersect_any(view, shadow, scratch.traversal, f.leaving(shadow))) return;
        if (highlight_skipped) ++scratch.stats.skipped.highlight_marker;
        color += light_term();
      },
      [&](ChildKind kind, const Ray& r, float w) {
        color += trace_ray(view, ctx, r, depth + 1, w, scratch, nullptr, f.leaving(r)) *
                 (kind == ChildKind::kReflected ? m.ks : m.transmittance);
      });
  return color;
}

}  // namespace raynode::core
