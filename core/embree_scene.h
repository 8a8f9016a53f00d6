// Embree 3 oracle: the same primitives as the grid, in an Embree scene.
//
// Place in the data flow: Database -> EmbreeScene -> `raynode validate`
// (compared ray by ray with the grid) and `--accel embree`. Triangles are
// Embree's native triangles (its own robust intersector, independent of
// ours); spheres are Embree's native sphere points; open cones are user
// geometry calling core::intersect_cone (Embree has no open cone).
// Primitive ids are the database's: geometry 0 holds the triangles, 1 the
// spheres, 2 the cones, and a per-geometry table maps Embree's primID back.
// Thread-safe for concurrent queries after construction.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/database.h"
#include "core/traverse.h"

namespace raynode::core {

class EmbreeScene {
 public:
  /// Builds the Embree scene (robust mode, high build quality). The database
  /// must outlive this object. Throws std::runtime_error with Embree's error
  /// text if Embree fails.
  explicit EmbreeScene(const Database& db);
  ~EmbreeScene();
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  /// Nearest hit in (ray.tmin, ray.tmax); hit.primitive is the database id.
  /// Barycentrics are filled for triangles. Both queries throw
  /// std::domain_error for a ray Embree cannot trace (a coordinate of its
  /// origin or direction beyond +-1.844e18, or a NaN interval).
  bool intersect_closest(const Ray& ray, Hit& hit) const;
  /// Any hit in (ray.tmin, ray.tmax).
  bool intersect_any(const Ray& ray) const;

  /// Bytes Embree's scene build kept: what its device allocated, less what
  /// it freed, while it built the acceleration structure (Embree's memory
  /// monitor, rtcSetDeviceMemoryMonitorFunction), so its BVH with the
  /// primitive copies in its leaves, not the geometry buffers it was given.
  /// The like-for-like figure for a grid's bytes with its packed cells.
  std::size_t build_bytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace raynode::core
