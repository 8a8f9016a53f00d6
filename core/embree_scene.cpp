#include "core/embree_scene.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>

#include <fmt/format.h>

#include "core/intersect.h"

namespace raynode::core {

namespace {

constexpr unsigned kTriangleGeometry = 0, kSphereGeometry = 1, kConeGeometry = 2;

struct ConeData {
  const Database* db;
  const std::vector<std::uint32_t>* ids;
};

void cone_bounds(const RTCBoundsFunctionArguments* args) {
  const auto* cd = static_cast<const ConeData*>(args->geometryUserPtr);
  const Bounds3 b = cd->db->primitives[(*cd->ids)[args->primID]].bounds();
  RTCBounds* o = args->bounds_o;
  o->lower_x = b.lower.x;
  o->lower_y = b.lower.y;
  o->lower_z = b.lower.z;
  o->upper_x = b.upper.x;
  o->upper_y = b.upper.y;
  o->upper_z = b.upper.z;
}

// std::nextafter(x, -inf), (x, +inf) and (x, 0) on the bits, inline: the
// library's nextafterf is a call, and open_interval_* run on every query
// that the accel bench times against the grid. x is not NaN.
inline float next_down(float x) {
  if (x == 0.0f) return -std::numeric_limits<float>::denorm_min();
  if (x == -kInfinity) return x;
  const std::uint32_t b = std::bit_cast<std::uint32_t>(x);
  return std::bit_cast<float>(x > 0.0f ? b - 1 : b + 1);
}
inline float next_up(float x) {
  if (x == 0.0f) return std::numeric_limits<float>::denorm_min();
  if (x == kInfinity) return x;
  const std::uint32_t b = std::bit_cast<std::uint32_t>(x);
  return std::bit_cast<float>(x > 0.0f ? b + 1 : b - 1);
}
inline float next_toward_zero(float x) {
  if (x == 0.0f) return 0.0f;
  return std::bit_cast<float>(std::bit_cast<std::uint32_t>(x) - 1);  // the magnitude's bits, one less
}

// Embree's ray interval [tnear, tfar] is closed; EmbreeScene passes the
// open interval (tmin, tmax) of a query as tnear = nextafter(tmin, +inf),
// tfar = nextafter(tmax, 0) (open_interval_*), and the cone test, whose
// interval is open, gets it back as (nextafter(tnear, -inf),
// nextafter(tfar, +inf)): the same interval as the grid's. The bounds
// are not NaN (check_traceable has thrown for a NaN interval).
inline float open_interval_near(float tmin) {
  // Not a subnormal: Embree's SIMD code slows down by ~20% (rings:4) on a
  // subnormal tnear. Hits at 0 < t < FLT_MIN (1.2e-38) are given up.
  return std::max(next_up(tmin), std::numeric_limits<float>::min());
}
inline float open_interval_far(float tmax) { return next_toward_zero(tmax); }

bool cone_hit(const ConeData* cd, unsigned prim_id, const RTCRay& r, float& t) {
  const Primitive& p = cd->db->primitives[(*cd->ids)[prim_id]];
  const float tmin = next_down(r.tnear), tmax = next_up(r.tfar);
  Ray ray{{r.org_x, r.org_y, r.org_z}, {r.dir_x, r.dir_y, r.dir_z}, tmin, tmax};
  return intersect_cone(ray, p.cone_base(), p.cone_base_radius(), p.cone_apex(), p.cone_apex_radius(), tmax, t);
}

void cone_intersect(const RTCIntersectFunctionNArguments* args) {
  if (!args->valid[0]) return;
  auto* rh = reinterpret_cast<RTCRayHit*>(args->rayhit);  // N == 1 for rtcIntersect1
  float t;
  if (!cone_hit(static_cast<const ConeData*>(args->geometryUserPtr), args->primID, rh->ray, t)) return;
  rh->ray.tfar = t;
  rh->hit.geomID = args->geomID;
  rh->hit.primID = args->primID;
  rh->hit.u = rh->hit.v = 0.0f;
  rh->hit.Ng_x = rh->hit.Ng_y = 0.0f;
  rh->hit.Ng_z = 1.0f;
  rh->hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
}

void cone_occluded(const RTCOccludedFunctionNArguments* args) {
  if (!args->valid[0]) return;
  auto* r = reinterpret_cast<RTCRay*>(args->ray);
  float t;
  if (cone_hit(static_cast<const ConeData*>(args->geometryUserPtr), args->primID, *r, t))
    r->tfar = -kInfinity;
}

[[noreturn]] void throw_embree(RTCDevice device, const char* what) {
  const RTCError e = rtcGetDeviceError(device);
  throw std::runtime_error(std::string("Embree: ") + what + " failed (error " + std::to_string(int(e)) + ")");
}

/// Embree 3 traces a ray only when every component of its origin and
/// direction is within +-FLT_LARGE (1.844e18, RayK::valid() in Embree's
/// kernels/common/ray.h) and its interval is not NaN; otherwise its debug
/// build aborts on an assertion and its release build may return garbage.
/// Throws std::domain_error naming the ray (a scene whose coordinates reach
/// that far cannot be checked against Embree).
void check_traceable(const Ray& ray) {
  constexpr float kEmbreeLarge = 1.844e18f;
  auto inside = [](const Vec3& v) {
    return std::fabs(v.x) <= kEmbreeLarge && std::fabs(v.y) <= kEmbreeLarge && std::fabs(v.z) <= kEmbreeLarge;
  };
  if (inside(ray.origin) && inside(ray.direction) && !std::isnan(ray.tmin) && !std::isnan(ray.tmax)) return;
  throw std::domain_error(fmt::format("Embree cannot trace a ray from ({}, {}, {}) in direction ({}, {}, {}): "
                                      "coordinates beyond +-{:g} (Embree's FLT_LARGE) or a NaN interval",
                                      ray.origin.x, ray.origin.y, ray.origin.z, ray.direction.x, ray.direction.y,
                                      ray.direction.z, kEmbreeLarge));
}

}  // namespace

struct EmbreeScene::Impl {
  const Database* db = nullptr;
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::vector<std::uint32_t> ids[3];  // per geometry: Embree primID -> database id
  ConeData cone_data{};
  std::atomic<std::int64_t> build_bytes{0};  // net bytes the device allocated during the build
};

namespace {

// Embree's memory monitor, set for the build only: called on its build
// threads, before an allocation with +bytes and after a free (or a failed
// allocation) with -bytes; never refuses.
bool count_build_bytes(void* user, ssize_t bytes, bool /*post*/) {
  static_cast<std::atomic<std::int64_t>*>(user)->fetch_add(std::int64_t(bytes), std::memory_order_relaxed);
  return true;
}

}  // namespace

EmbreeScene::EmbreeScene(const Database& db) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.db = &db;
  m.device = rtcNewDevice("verbose=0");
  if (!m.device) throw std::runtime_error("Embree: cannot create a device");
  m.scene = rtcNewScene(m.device);
  rtcSetSceneFlags(m.scene, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(m.scene, RTC_BUILD_QUALITY_HIGH);

  for (std::uint32_t i = 0; i < db.primitives.size(); ++i) m.ids[int(db.primitives[i].kind)].push_back(i);

  // Geometry ids are fixed (0 triangles, 1 spheres, 2 cones) even when a kind
  // is absent, so that geomID indexes `ids` directly.
  {
    RTCGeometry g = rtcNewGeometry(m.device, RTC_GEOMETRY_TYPE_TRIANGLE);
    const std::size_t n = m.ids[0].size();
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), 3 * n + 1));
    auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                3 * sizeof(unsigned), n));
    if ((!v || !idx) && n) throw_embree(m.device, "triangle buffer allocation");
    for (std::size_t k = 0; k < n; ++k) {
      const Primitive& p = db.primitives[m.ids[0][k]];
      for (int j = 0; j < 9; ++j) v[9 * k + j] = p.data[j];
      for (int j = 0; j < 3; ++j) idx[3 * k + j] = unsigned(3 * k + j);
    }
    rtcCommitGeometry(g);
    rtcAttachGeometryByID(m.scene, g, kTriangleGeometry);
    rtcReleaseGeometry(g);
  }
  {
    RTCGeometry g = rtcNewGeometry(m.device, RTC_GEOMETRY_TYPE_SPHERE_POINT);
    const std::size_t n = m.ids[1].size();
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4,
                                                          4 * sizeof(float), n));
    if (!v && n) throw_embree(m.device, "sphere buffer allocation");
    for (std::size_t k = 0; k < n; ++k) {
      const Primitive& p = db.primitives[m.ids[1][k]];
      for (int j = 0; j < 3; ++j) v[4 * k + j] = p.data[j];
      v[4 * k + 3] = std::fabs(p.radius());
    }
    rtcCommitGeometry(g);
    rtcAttachGeometryByID(m.scene, g, kSphereGeometry);
    rtcReleaseGeometry(g);
  }
  {
    RTCGeometry g = rtcNewGeometry(m.device, RTC_GEOMETRY_TYPE_USER);
    m.cone_data = ConeData{&db, &m.ids[2]};
    rtcSetGeometryUserPrimitiveCount(g, unsigned(m.ids[2].size()));
    rtcSetGeometryUserData(g, &m.cone_data);
    rtcSetGeometryBoundsFunction(g, cone_bounds, nullptr);
    rtcSetGeometryIntersectFunction(g, cone_intersect);
    rtcSetGeometryOccludedFunction(g, cone_occluded);
    rtcCommitGeometry(g);
    rtcAttachGeometryByID(m.scene, g, kConeGeometry);
    rtcReleaseGeometry(g);
  }
  rtcSetDeviceMemoryMonitorFunction(m.device, count_build_bytes, &m.build_bytes);
  rtcCommitScene(m.scene);
  rtcSetDeviceMemoryMonitorFunction(m.device, nullptr, nullptr);
  if (rtcGetDeviceError(m.device) != RTC_ERROR_NONE) throw_embree(m.device, "scene build");
}

EmbreeScene::~EmbreeScene() {
  if (impl_) {
    if (impl_->scene) rtcReleaseScene(impl_->scene);
    if (impl_->device) rtcReleaseDevice(impl_->device);
  }
}

std::size_t EmbreeScene::build_bytes() const {
  return std::size_t(std::max<std::int64_t>(0, impl_->build_bytes.load(std::memory_order_relaxed)));
}

bool EmbreeScene::intersect_closest(const Ray& ray, Hit& hit) const {
  check_traceable(ray);
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh{};
  rh.ray.org_x = ray.origin.x;
  rh.ray.org_y = ray.origin.y;
  rh.ray.org_z = ray.origin.z;
  rh.ray.dir_x = ray.direction.x;
  rh.ray.dir_y = ray.direction.y;
  rh.ray.dir_z = ray.direction.z;
  rh.ray.tnear = open_interval_near(ray.tmin);  // open interval, see cone_hit
  rh.ray.tfar = open_interval_far(ray.tmax);
  rh.ray.mask = 0xffffffffu;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, &ctx, &rh);
  hit = Hit{};
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
  hit.t = rh.ray.tfar;
  hit.primitive = impl_->ids[rh.hit.geomID][rh.hit.primID];
  hit.u = rh.hit.u;
  hit.v = rh.hit.v;
  return true;
}

bool EmbreeScene::intersect_any(const Ray& ray) const {
  check_traceable(ray);
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRay r{};
  r.org_x = ray.origin.x;
  r.org_y = ray.origin.y;
  r.org_z = ray.origin.z;
  r.dir_x = ray.direction.x;
  r.dir_y = ray.direction.y;
  r.dir_z = ray.direction.z;
  r.tnear = open_interval_near(ray.tmin);  // open interval, see cone_hit
  r.tfar = open_interval_far(ray.tmax);
  r.mask = 0xffffffffu;
  rtcOccluded1(impl_->scene, &ctx, &r);
  return r.tfar < 0.0f;
}

}  // namespace raynode::core
