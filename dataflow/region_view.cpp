#include "dataflow/region_view.h"

#include <algorithm>
#include <limits>

namespace raynode::dataflow {

std::size_t RegionDatabase::bytes() const {
  return db.primitives.size() * sizeof(core::Primitive) + db.vertex_normals.size() * sizeof(core::TriangleNormals) +
         db.materials.size() * sizeof(core::Material) + grid.bytes() + shared.size();
}

namespace {

/// 2D screen-frame box of a primitive's projection (conservative).
ScreenRect footprint(const CameraFrame& f, const core::Primitive& p) {
  ScreenRect r{core::kInfinity, core::kInfinity, -core::kInfinity, -core::kInfinity};
  auto add = [&](const core::Vec3& q, float radius) {
    const float x = f.x(q), y = f.y(q);
    r.x0 = std::min(r.x0, x - radius), r.x1 = std::max(r.x1, x + radius);
    r.y0 = std::min(r.y0, y - radius), r.y1 = std::max(r.y1, y + radius);
  };
  switch (p.kind) {
    case core::PrimitiveKind::kTriangle:
      for (int i = 0; i < 3; ++i) add(p.vertex(i), 0.0f);
      break;
    case core::PrimitiveKind::kSphere: add(p.center(), std::fabs(p.radius())); break;
    case core::PrimitiveKind::kCone: {
      const float rad = std::max(std::fabs(p.cone_base_radius()), std::fabs(p.cone_apex_radius()));
      add(p.cone_base(), rad);
      add(p.cone_apex(), rad);
      break;
    }
  }
  return r;
}

bool overlaps(const ScreenRect& a, const ScreenRect& b, float pad) {
  return a.x0 <= b.x1 + pad && b.x0 - pad <= a.x1 && a.y0 <= b.y1 + pad && b.y0 - pad <= a.y1;
}

}  // namespace

std::vector<RegionDatabase> make_region_databases(const core::Database& db, const Partition& partition,
                                                  const core::GridParams& grid_params) {
  const CameraFrame& f = partition.frame;
  const ScreenRect& e = partition.extent;
  const std::uint32_t n = partition.region_count();
  const float size = std::max(e.x1 - e.x0, e.y1 - e.y0);
  const float mag = std::max({std::fabs(e.x0), std::fabs(e.x1), std::fabs(e.y0), std::fabs(e.y1)});
  const float pad = 1e-4f * size + 64.0f * std::numeric_limits<float>::epsilon() * mag;

  // Depth range of the scene along the view axis.
  core::Bounds3 sb = db.bounds;
  if (sb.empty()) sb = core::Bounds3{{-1, -1, -1}, {1, 1, 1}};
  float z0 = core::kInfinity, z1 = -core::kInfinity;
  for (int i = 0; i < 8; ++i) {
    const core::Vec3 p{(i & 1) ? sb.upper.x : sb.lower.x, (i & 2) ? sb.upper.y : sb.lower.y,
                       (i & 4) ? sb.upper.z : sb.lower.z};
    z0 = std::min(z0, f.z(p)), z1 = std::max(z1, f.z(p));
  }
  const float zpad = 1e-4f * std::max(z1 - z0, size) + 64.0f * std::numeric_limits<float>::epsilon() *
                                                           std::max(std::fabs(z0), std::fabs(z1));
  z0 -= zpad, z1 += zpad;

  // Which regions each primitive overlaps.
  std::vector<std::vector<std::uint32_t>> members(n);
  std::vector<std::uint32_t> copies(db.primitives.size(), 0);
  for (std::uint32_t pi = 0; pi < db.primitives.size(); ++pi) {
    const ScreenRect fp = footprint(f, db.primitives[pi]);
    for (std::uint32_t r = 0; r < n; ++r)
      if (overlaps(fp, partition.rects[r], pad)) {
        members[r].push_back(pi);
        ++copies[pi];
      }
  }

  // Every region's grid traces in the whole scene's frame, as the other
  // modes' grids do, so that a ray is tested alike everywhere.
  core::GridParams params = grid_params;
  if (params.frame_magnitude <= 0) params.frame_magnitude = core::frame_magnitude(db);
  std::vector<RegionDatabase> out(n);
  for (std::uint32_t r = 0; r < n; ++r) {
    RegionDatabase& rd = out[r];
    rd.db.materials = db.materials;
    rd.db.lights = db.lights;
    rd.db.view = db.view;
    rd.db.has_view = db.has_view;
    rd.db.background = db.background;
    rd.db.shape_count = db.shape_count;
    rd.db.degenerate_triangles_dropped = db.degenerate_triangles_dropped;
    rd.global = members[r];
    rd.shared.resize(rd.global.size());
    rd.db.primitives.reserve(rd.global.size());
    core::Bounds3 prim_bounds;
    for (std::size_t i = 0; i < rd.global.size(); ++i) {
      core::Primitive p = db.primitives[rd.global[i]];
      if (p.kind == core::PrimitiveKind::kTriangle && p.normals != core::kNoNormals) {
        rd.db.vertex_normals.push_back(db.vertex_normals[p.normals]);
        p.normals = std::uint32_t(rd.db.vertex_normals.size() - 1);
      }
      prim_bounds.extend(p.bounds());
      rd.db.primitives.push_back(p);
      rd.shared[i] = copies[rd.global[i]] > 1 ? 1 : 0;
    }
    // The region's box in world space: its (finite) rectangle x the depth range.
    const ScreenRect& q = partition.finite[r];
    core::Bounds3 box;
    for (int i = 0; i < 8; ++i) {
      const float x = (i & 1) ? q.x1 + pad : q.x0 - pad;
      const float y = (i & 2) ? q.y1 + pad : q.y0 - pad;
      const float z = (i & 4) ? z1 : z0;
      box.extend(f.origin + f.u * x + f.v * y + f.w * z);
    }
    core::Bounds3 b;
    b.lower = core::max(box.lower, prim_bounds.lower);
    b.upper = core::min(box.upper, prim_bounds.upper);
    rd.db.bounds = b.empty() ? prim_bounds : b;
    rd.grid = core::build_grid(rd.db, params);
  }
  return out;
}

}  // namespace raynode::dataflow
