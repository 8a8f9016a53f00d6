// The tracing database: the scene as the tracer sees it.
//
// Place in the data flow: Scene (file order, NFF entities) -> make_database ->
// Database (flat array of fixed-size Primitive records, triangles with
// optional vertex normals, materials, lights, view) -> build_grid (grid.h).
// Polygons with more than 3 vertices, convex or concave, are split into
// triangles by ear clipping; every record remembers the NFF shape it came
// from (`shape`, its index in file order) so images and AOVs can name it.
//
// A Primitive is 64 bytes, one cache line; svm pages these records
// (docs/architecture.md "svm"), so they hold no pointers, only indices.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/math.h"
#include "core/scene.h"

namespace raynode::core {

/// Kinds of tracing primitive.
enum class PrimitiveKind : std::uint8_t { kTriangle = 0, kSphere = 1, kCone = 2 };

inline constexpr std::uint32_t kNoNormals = 0xffffffffu;
inline constexpr std::uint32_t kNoPrimitive = 0xffffffffu;

/// One tracing primitive. `data` holds, by kind:
///   triangle: v0.xyz v1.xyz v2.xyz (counter-clockwise seen from the front)
///   sphere:   center.xyz radius
///   cone:     base.xyz base_radius apex.xyz apex_radius
struct alignas(64) Primitive {
  PrimitiveKind kind = PrimitiveKind::kTriangle;
  std::uint8_t reserved0 = 0;
  std::uint16_t reserved1 = 0;
  std::uint32_t material = 0;          ///< index into Database::materials
  std::uint32_t shape = 0;             ///< index of the NFF shape (file order)
  std::uint32_t normals = kNoNormals;  ///< triangle from `pp`: index into Database::vertex_normals
  float data[12] = {};

  Vec3 vertex(int i) const { return {data[3 * i], data[3 * i + 1], data[3 * i + 2]}; }
  Vec3 center() const { return {data[0], data[1], data[2]}; }
  float radius() const { return data[3]; }
  Vec3 cone_base() const { return {data[0], data[1], data[2]}; }
  float cone_base_radius() const { return data[3]; }
  Vec3 cone_apex() const { return {data[4], data[5], data[6]}; }
  float cone_apex_radius() const { return data[7]; }

  /// World-space bounds (conservative).
  Bounds3 bounds() const;
};
static_assert(sizeof(Primitive) == 64, "a primitive is one cache line");

/// Per-vertex normals of a triangle that came from a `pp` patch.
struct TriangleNormals {
  Vec3 n[3];
};

/// Counts of the database's records by kind.
struct DatabaseCounts {
  std::size_t triangles = 0;
  std::size_t spheres = 0;
  std::size_t cones = 0;
  std::size_t vertex_normal_sets = 0;
};

/// The whole tracing database (the host's copy). Trivially relocatable
/// vectors of plain records; nothing points anywhere.
struct Database {
  std::vector<Primitive> primitives;
  std::vector<TriangleNormals> vertex_normals;
  std::vector<Material> materials;
  std::vector<Light> lights;
  View view;
  bool has_view = false;
  Vec3 background;
  Bounds3 bounds;               ///< of all primitives
  std::size_t shape_count = 0;  ///< NFF shapes it was made from
  std::size_t dropped_degenerate_triangles = 0;  ///< zero-area pieces of polygons
  /// True when no triangle is degenerate (triangle_is_degenerate, intersect.h):
  /// make_database dropped them (DatabaseParams::drop_degenerate). Otherwise
  /// build_grid leaves them out of its lists, and either way the grid's
  /// walk never tests them.
  bool degenerate_triangles_dropped = false;

  DatabaseCounts counts() const;
  /// Bytes of primitive, normal and material records (the paper's "database size").
  std::size_t bytes() const;
};

/// Options for make_database.
struct DatabaseParams {
  /// Also drop triangles whose area is ~0 after splitting a polygon (on by default).
  bool drop_degenerate = true;
};

/// Builds the tracing database from a scene. Polygons and patches are split
/// into triangles (ear clipping on the polygon's dominant plane; handles
/// concave polygons such as the SPD gears faces), spheres and cones are kept
/// analytic. Throws std::invalid_argument if the scene has more than 2^32-2
/// primitives or a concave polygon that is too long (triangulate_polygon,
/// naming the shape), StopError when a stop is requested (core/stop.h).
Database make_database(const Scene& scene, const DatabaseParams& params = {});

/// Polygons of at most this many vertices are always split by ear clipping,
/// as they always were; above it a polygon that splits_in_linear_time (every
/// convex one) is split in O(n).
inline constexpr std::uint32_t kEarClippingVertices = 1024;
/// The most vertices a longer polygon that does not split in linear time
/// (concave, and not star-shaped from its last vertex) may have: ear
/// clipping takes O(n^2) time (0.5-1.6 s at this count). The NFF reader
/// refuses a longer one with its location.
inline constexpr std::uint32_t kMaxConcavePolygonVertices = 20000;
/// How much more than the polygon's area the triangles of a linear-time
/// split may cover in all (relative): room for the tiny triangles that turn
/// over where rounding of the coordinates makes a convex outline zig-zag (a
/// 300000-vertex circle written with 6 digits: 2.9e-6 with the fan).
inline constexpr double kFanAreaTolerance = 1e-5;

/// True when the polygon, projected on its dominant plane as
/// triangulate_polygon projects it, is covered once, within
/// kFanAreaTolerance of its area, by the balanced split (triangle (0, n/2,
/// n-1), then the same within each chain it cuts off: true of every convex
/// polygon) or by the fan around its last vertex (true of one star-shaped
/// from that vertex). O(n) time.
bool splits_in_linear_time(const Vec3* verts, std::uint32_t n);

/// Splits a planar polygon (n >= 3 vertices, convex or concave, simple) into
/// n-2 triangles; appends vertex-index triples (into `verts`) to `out`, each
/// ordered like the polygon (same facing). Zero-area triangles are skipped
/// when `drop_degenerate`. Up to kEarClippingVertices vertices, and for any
/// longer polygon that does not split_in_linear_time, by ear clipping
/// (Eberly, "Triangulation by Ear Clipping", 2002; O(n^2)); a longer one
/// that does is split in O(n), by the balanced split where it covers the
/// polygon (its triangles halve in size level by level, which a grid lists
/// in few cells), else by the fan.
/// Throws std::invalid_argument for a polygon that does not split in linear
/// time with more than kMaxConcavePolygonVertices vertices, StopError when a
/// stop is requested (core/stop.h).
void triangulate_polygon(const Vec3* verts, std::uint32_t n, std::vector<std::uint32_t>& out,
                         bool drop_degenerate = true);

}  // namespace raynode::core
