// EmbreeView: a database view whose closest-hit and any-hit queries go to
// Embree 3 (EmbreeScene) instead of the uniform grid, so that `raynode
// render --accel embree` shades with the very same trace_ray / render_image
// templates (shade.h, render.h) as the grid.
//
// Place in the data flow: Database -> EmbreeScene -> EmbreeView ->
// render_image. The customisation point is plain overloading: the
// non-template intersect_closest / intersect_any below (namespace
// raynode::core, found by argument-dependent lookup from the templates in
// shade.h and render.h) are preferred to the grid templates of traverse.h
// for an EmbreeView, so the grid path is untouched.
//
// Embree chooses *which* primitive is hit; the hit's distance and
// barycentrics are then recomputed by raynode's own test of that primitive
// (intersect.h), the same arithmetic the grid uses. So wherever the grid and
// Embree agree on the primitive, depth, normal, shading and every
// secondary ray are bit-identical; they can differ only where the two
// accelerators pick different primitives (grazing edges, coincident
// surfaces). If raynode's test misses the primitive Embree reported
// (an edge hair), or finds a root more than 1e-3 relative away from
// Embree's, Embree's own t/u/v are kept.
//
// Counters: TraversalStats::rays is counted; cells_visited and the
// per-kind test counts stay 0 (Embree does not report them).
#pragma once

#include <cmath>
#include <cstdint>

#include "core/database.h"
#include "core/embree_scene.h"
#include "core/intersect.h"
#include "core/traverse.h"

namespace raynode::core {

/// View over `db` and an EmbreeScene built from it; both must outlive the
/// view. Cheap to copy. Thread-safe (Embree queries are; the view holds no
/// mutable state).
class EmbreeView {
 public:
  EmbreeView(const Database& db, const EmbreeScene& scene)
      : db_(&db), scene_(&scene), frame_(frame_magnitude(db)) {}

  const Primitive& primitive(std::uint32_t id) const { return db_->primitives[id]; }
  const Material& material(std::uint32_t id) const { return db_->materials[id]; }
  const TriangleNormals& vertex_normals(std::uint32_t id) const { return db_->vertex_normals[id]; }
  const Database& database() const { return *db_; }
  const EmbreeScene& scene() const { return *scene_; }
  /// The grid's tracing frame over the same database (frame_magnitude), in
  /// which the hit Embree reports is recomputed.
  float frame() const { return frame_; }

 private:
  const Database* db_;
  const EmbreeScene* scene_;
  float frame_;
};

/// Nearest hit of `ray` in (ray.tmin, ray.tmax) through Embree, with t, u, v
/// recomputed by raynode's own primitive test (see the file comment).
/// Returns hit.found(); on a miss `hit` is Hit{}. Counts one ray in
/// scratch.stats. Precondition: is_valid_ray(ray). The triangle the ray
/// leaves is Embree's to test (the answer is the same: intersect_closest).
inline bool intersect_closest(const EmbreeView& view, const Ray& ray, Hit& hit, TraversalScratch& scratch,
                              std::uint32_t /*origin_triangle*/ = kNoPrimitive) {
  ++scratch.stats.rays;
  if (!view.scene().intersect_closest(ray, hit)) {
    hit = Hit{};
    return false;
  }
  // Recomputed as the grid tests it, in the tracing frame (closest_in_frame).
  Hit exact;
  const Primitive& p = view.primitive(hit.primitive);
  const std::uint32_t id = hit.primitive;
  const bool found = closest_in_frame(view.frame(), ray, exact, [&](const Ray& piece, Hit& h) {
    h = Hit{};
    h.t = piece.tmax;
    TraversalStats ignored;
    const WatertightRay w(piece.direction);
    return intersect_primitive(p, id, piece, w, h, ignored);
  });
  if (found && std::fabs(exact.t - hit.t) <= 1e-3f * std::fmax(1.0f, hit.t)) hit = exact;
  return true;
}

/// True if anything lies on `ray` in (ray.tmin, ray.tmax), through Embree's
/// occlusion query. Counts one ray in scratch.stats. The triangle the ray
/// leaves is Embree's to test.
inline bool intersect_any(const EmbreeView& view, const Ray& ray, TraversalScratch& scratch,
                          std::uint32_t /*origin_triangle*/ = kNoPrimitive) {
  ++scratch.stats.rays;
  return view.scene().intersect_any(ray);
}

}  // namespace raynode::core
