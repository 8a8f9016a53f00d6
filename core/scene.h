// raynode scene model: everything an NFF file holds, in file order.
//
// Place in the data flow: the NFF reader (nff.h) and the SPD generators
// (spd.h) produce a Scene; the writer turns it back into NFF; `make_database`
// (database.h) turns it into the tracing form (triangles, spheres, cones with
// material ids) that the grid, the tracer and the parallel modes use.
// Source: Eric Haines, "Neutral File Format" (SPD 3.14) and
// docs/nff.md.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/math.h"

namespace raynode::core {

/// NFF `f r g b Kd Ks Shine T ior`: a surface material. All weights are
/// dimensionless; `shine` is a Phong exponent (100000 = "no highlight" marker).
struct Material {
  Vec3 color{1.0f, 1.0f, 1.0f};  ///< surface colour, 0..1 per channel
  float kd = 1.0f;               ///< diffuse weight
  float ks = 0.0f;               ///< mirror reflection (and highlight) weight
  float shine = 0.0f;            ///< Phong exponent
  float transmittance = 0.0f;    ///< T: refracted-ray weight, 0..1
  float ior = 1.0f;              ///< index of refraction (meaningful only when T > 0)
  friend bool operator==(const Material&, const Material&) = default;
};

/// NFF `l x y z [r g b]`: a point light.
struct Light {
  Vec3 position;
  Vec3 color{1.0f, 1.0f, 1.0f};
  bool has_color = false;  ///< the file gave the optional colour
  friend bool operator==(const Light&, const Light&) = default;
};

/// NFF `v` block: the camera. `angle` is the full field of view in degrees
/// between the centres of the outer pixels (docs/nff.md, "The view block").
struct View {
  Vec3 from{0.0f, 0.0f, 0.0f};
  Vec3 at{0.0f, 0.0f, -1.0f};
  Vec3 up{0.0f, 1.0f, 0.0f};
  float angle = 45.0f;  ///< degrees
  float hither = 0.0f;  ///< near distance, world units
  int width = 512;      ///< pixels
  int height = 512;     ///< pixels
  friend bool operator==(const View&, const View&) = default;
};

/// The kinds of NFF primitive.
enum class ShapeKind : std::uint8_t {
  kPolygon,  ///< `p`: planar polygon, n >= 3 vertices, convex or concave
  kPatch,    ///< `pp`: polygon with a normal at each vertex
  kSphere,   ///< `s`
  kCone,     ///< `c`: open cone or cylinder (no caps)
};

/// `s cx cy cz r`. A negative radius means "inside visible" (never in SPD).
struct Sphere {
  Vec3 center;
  float radius = 1.0f;
  friend bool operator==(const Sphere&, const Sphere&) = default;
};

/// `c bx by bz br ax ay az ar`: open cone/cylinder from base centre (radius
/// base_radius) to apex centre (radius apex_radius).
struct Cone {
  Vec3 base;
  float base_radius = 1.0f;
  Vec3 apex;
  float apex_radius = 0.0f;
  friend bool operator==(const Cone&, const Cone&) = default;
};

/// One primitive of the file, in file order. Its geometry lives in the
/// per-kind arrays of Scene: for kPolygon/kPatch, `count` vertices starting at
/// Scene::vertices[first] (and for kPatch, normals at Scene::normals[first_normal]);
/// for kSphere, Scene::spheres[first]; for kCone, Scene::cones[first].
struct Shape {
  ShapeKind kind = ShapeKind::kPolygon;
  std::uint32_t material = 0;      ///< index into Scene::materials
  std::uint32_t first = 0;         ///< see above
  std::uint32_t count = 0;         ///< vertex count (polygon/patch), 1 otherwise
  std::uint32_t first_normal = 0;  ///< kPatch only
};

/// Counts per entity kind, as `raynode scene info` and SPD's MANIFEST report them.
struct SceneCounts {
  std::size_t polygons = 0;   ///< `p`
  std::size_t patches = 0;    ///< `pp`
  std::size_t spheres = 0;    ///< `s`
  std::size_t cones = 0;      ///< `c`
  std::size_t lights = 0;     ///< `l`
  std::size_t materials = 0;  ///< `f`
  std::size_t dropped_degenerate = 0;  ///< zero-area polygons dropped on input
  friend bool operator==(const SceneCounts&, const SceneCounts&) = default;
};

/// A whole NFF scene. Materials are kept as the file's sequence of `f`
/// statements (not deduplicated); each shape refers to the one in force.
struct Scene {
  View view;
  bool has_view = false;
  Vec3 background{0.0f, 0.0f, 0.0f};
  std::vector<Light> lights;
  std::vector<Material> materials;
  std::vector<Shape> shapes;      ///< primitives in file order
  std::vector<Vec3> vertices;     ///< polygon and patch vertices
  std::vector<Vec3> normals;      ///< patch vertex normals
  std::vector<Sphere> spheres;
  std::vector<Cone> cones;
  std::size_t dropped_degenerate = 0;  ///< zero-area polygons dropped by the reader

  /// Index of the material in force for the next shape; adds a default
  /// material if none has been given yet.
  std::uint32_t current_material();

  /// Appends shapes; each uses the current material (materials.back()).
  void add_polygon(const Vec3* verts, std::uint32_t n);
  void add_patch(const Vec3* verts, const Vec3* vertex_normals, std::uint32_t n);
  void add_sphere(const Sphere& s);
  void add_cone(const Cone& c);

  SceneCounts counts() const;
  /// World-space bounds of all primitives (empty box for an empty scene).
  Bounds3 bounds() const;
};

/// True when the polygon's vertices span (nearly) zero area: the magnitude of
/// the Newell normal is <= rel_eps * (longest edge)^2. Such polygons are
/// dropped by the reader and counted (Scene::dropped_degenerate).
bool is_degenerate_polygon(const Vec3* verts, std::uint32_t n, float rel_eps = 1e-7f);

}  // namespace raynode::core
