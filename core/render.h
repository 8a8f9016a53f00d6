// The Whitted renderer over a database view: pixels -> camera rays ->
// trace_ray (shade.h) -> a float RGB image (+ depth, normal and primitive
// AOVs of the centre ray's first hit).
//
// Place in the data flow: Database + Grid -> a database view (DirectView;
// EmbreeView for --accel embree, embree_view.h; svm's PagedView and dataflow's
// RegionView in their folders)
// -> render_pixel for each pixel ->
// core::Image -> imageio::write_image_as (apps only). Sequential and shared
// modes compute each pixel with the same code, independent of the thread,
// so their images are bit-identical.
//
// Supersampling: --spp N fires N x N rays per pixel at the fixed stratified
// offsets ((i + 0.5) / N, (j + 0.5) / N) within the pixel (no randomness),
// and averages them in a fixed order.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <fmt/core.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "core/camera.h"
#include "core/database.h"
#include "core/direct_view.h"
#include "core/grid.h"
#include "core/image.h"
#include "core/shade.h"
#include "core/stop.h"
#include "core/traverse.h"

namespace raynode::core {

/// How the pixels are distributed.
enum class RenderMode { kSequential, kShared };

/// Parses "sequential" / "shared"; throws std::invalid_argument otherwise.
RenderMode parse_render_mode(const std::string& name);
const char* render_mode_name(RenderMode mode);

/// Render options; every field has a default.
struct RenderParams {
  int width = 0;            ///< pixels; 0 = the view's resolution
  int height = 0;           ///< pixels; 0 = the view's resolution
  int spp = 1;              ///< N: N x N stratified samples per pixel, N >= 1
  int max_depth = 5;        ///< ray levels (eye ray = 1), >= 1
  float min_weight = 0.0f;  ///< Hall & Greenberg pruning threshold, 0 = off
  ShadowRays shadow_rays = ShadowRays::kFacing;  ///< lights a hit casts shadow rays to
  bool depth_aov = false;   ///< also produce the depth image
  bool normal_aov = false;  ///< also produce the normal image
  bool primitive_aov = false;  ///< also produce the primitive (NFF shape index) image
  RenderMode mode = RenderMode::kSequential;
  int tile_size = 16;       ///< shared mode: square tiles of this many pixels
  /// When non-null, render_image adds the number of finished pixels to it
  /// (relaxed order, once per row in sequential mode, once per tile in shared
  /// mode) so that another thread can show progress. Never read by the
  /// renderer; it does not change the image.
  std::atomic<std::uint64_t>* progress = nullptr;
  /// Wall seconds render_image may take, 0 = no limit: it reads the clock
  /// after each row (sequential) or tile (shared) and throws RenderTimeout
  /// once the limit has passed (the node modes have their own watchdog,
  /// nodes::MachineParams::timeout_s). Does not change the image.
  double timeout_s = 0;

  /// True when any AOV (first-hit image) is requested.
  bool any_aov() const { return depth_aov || normal_aov || primitive_aov; }
};

/// Thrown by render_image when RenderParams::timeout_s has passed; the
/// message names the limit and the pixels done.
class RenderTimeout : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A rendered frame. Every AOV describes the first hit of the primary ray
/// through the pixel centre (camera.ray_through(x + 0.5, y + 0.5)).
struct RenderResult {
  Image color;      ///< linear RGB, width x height
  Image depth;      ///< 1 channel: eye-to-first-hit distance (world units), +inf on a miss; empty unless requested
  Image normal;     ///< 3 channels: unit shading normal at the first hit, face-forwarded towards the eye
                    ///< (interpolated for `pp` triangles), world space; (0, 0, 0) on a miss; empty unless requested
  Image primitive;  ///< 1 channel: index in file order of the NFF shape (`p`, `pp`, `s`, `c` statement, counted
                    ///< from 0 over all shapes of the scene as loaded, i.e. after --tessellate) that the hit
                    ///< primitive came from (Primitive::shape: every triangle of a split polygon carries its
                    ///< polygon's index); -1 on a miss. Stored as float: exact below 2^24 shapes.
                    ///< Empty unless requested.
  RenderStats stats;  ///< summed over all threads
};

/// One pixel's results.
struct PixelResult {
  Vec3 color;
  FirstHit first;  ///< centre ray's first hit; meaningful only when requested (want_first_hit)
};

/// The view used for rendering `db`: its file view, or (no view block) one
/// looking at the centre of the bounds from a fixed oblique direction, 1.5
/// bounds diagonals away (farther for a scene tiny against its distance from
/// the origin, so that float rounding cannot collapse the viewing direction).
/// Throws std::runtime_error when the bounds reach so far that the default
/// camera position overflows float.
View render_view(const Database& db);

/// Colour of pixel (x, y), 0 <= x < width, 0 <= y < height of `camera`, and
/// (when `want_first_hit`) the first hit of the ray through its centre.
/// Casts spp x spp primary rays at offsets ((i + 0.5) / spp, (j + 0.5) / spp);
/// for odd spp the middle one passes exactly through the pixel centre and
/// gives the first hit; when `want_first_hit` and spp is even, one extra
/// primary ray (counted as primary, not shaded) is cast through the centre.
/// Usable by any caller that owns a subset of the pixels (e.g. a node
/// thread with its own view). Owner thread of `scratch` only.
template <class View>
PixelResult render_pixel(const View& view, const ShadingContext& ctx, const Camera& camera, int x, int y, int spp,
                         bool want_first_hit, ShadingScratch& scratch) {
  PixelResult out;
  Vec3 sum;
  const float n = float(spp);
  const bool centre_sampled = (spp % 2) == 1;
  const int centre = spp / 2;
  for (int j = 0; j < spp; ++j)
    for (int i = 0; i < spp; ++i) {
      const Ray r = camera.ray_through(float(x) + (float(i) + 0.5f) / n, float(y) + (float(j) + 0.5f) / n);
      ++scratch.stats.rays.primary;
      const bool is_centre = want_first_hit && centre_sampled && i == centre && j == centre;
      sum += trace_ray(view, ctx, r, 1, 1.0f, scratch, is_centre ? &out.first : nullptr);
    }
  out.color = sum * (1.0f / float(spp * spp));
  if (want_first_hit && !centre_sampled) {
    const Ray r = camera.ray_through(float(x) + 0.5f, float(y) + 0.5f);
    ++scratch.stats.rays.primary;
    Hit hit;
    if (intersect_closest(view, r, hit, scratch.traversal)) {
      const Primitive prim = view.primitive(hit.primitive);  // a copy: see trace_ray
      out.first = FirstHit{hit.t, surface_frame(view, prim, r, hit).ns, std::int64_t(prim.shape)};
    }
  }
  return out;
}

/// Renders pixels [x0, x1) x [y0, y1) into `result`: the colour image and
/// each AOV image that is non-empty (all already sized by the caller to the
/// camera's resolution). Owner thread of `scratch` only; concurrent calls
/// on disjoint rectangles are safe.
template <class View>
void render_rect(const View& view, const ShadingContext& ctx, const Camera& camera, const RenderParams& params,
                 int x0, int y0, int x1, int y1, RenderResult& result, ShadingScratch& scratch) {
  const bool want_first = !result.depth.empty() || !result.normal.empty() || !result.primitive.empty();
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) {
      const PixelResult px = render_pixel(view, ctx, camera, x, y, params.spp, want_first, scratch);
      float* c = result.color.at(x, y);
      c[0] = px.color.x;
      c[1] = px.color.y;
      c[2] = px.color.z;
      if (!want_first) continue;
      if (!result.depth.empty()) *result.depth.at(x, y) = px.first.t;
      if (!result.normal.empty()) {
        float* nrm = result.normal.at(x, y);
        nrm[0] = px.first.normal.x;
        nrm[1] = px.first.normal.y;
        nrm[2] = px.first.normal.z;
      }
      if (!result.primitive.empty()) *result.primitive.at(x, y) = float(px.first.shape);
    }
}

/// Renders the whole image in params.mode. Sequential: one thread, row by
/// row. Shared: tbb::parallel_for over tile_size^2 tiles, one ShadingScratch
/// per worker thread (tbb::enumerable_thread_specific), counters merged at
/// the end. `view` is any database view (DirectView, EmbreeView, ...) over
/// `db`. Throws std::invalid_argument for bad params or camera,
/// RenderTimeout when params.timeout_s has passed.
template <class View>
RenderResult render_image(const View& view, const Database& db, const RenderParams& params) {
  if (params.spp < 1) throw std::invalid_argument("spp must be >= 1");
  if (params.max_depth < 1) throw std::invalid_argument("max depth must be >= 1");
  if (params.tile_size < 1) throw std::invalid_argument("tile size must be >= 1");
  const View& v = view;
  const core::View cam_view = render_view(db);
  const int w = params.width > 0 ? params.width : cam_view.width;
  const int h = params.height > 0 ? params.height : cam_view.height;
  const Camera camera(cam_view, w, h);
  const ShadingContext ctx = make_shading_context(db, params.max_depth, params.min_weight, params.shadow_rays);
  RenderResult result;
  result.color = Image(w, h, 3);
  if (params.depth_aov) result.depth = Image(w, h, 1);
  if (params.normal_aov) result.normal = Image(w, h, 3);
  if (params.primitive_aov) result.primitive = Image(w, h, 1);
  std::atomic<std::uint64_t>* progress = params.progress;
  // --timeout: the clock is read once per row or tile (~20 ns against a row's
  // tens of microseconds at least), and a process-wide stop request
  // (core/stop.h: the CLI's watchdog, counted from process start) is polled
  // there too; trace_ray polls it for every ray.
  using Clock = std::chrono::steady_clock;
  const Clock::time_point start = Clock::now();
  std::atomic<std::uint64_t> pixels_done{0};
  const std::uint64_t all_pixels = std::uint64_t(w) * std::uint64_t(h);
  auto check_time = [&](std::uint64_t pixels) {
    const std::uint64_t done = pixels_done.fetch_add(pixels, std::memory_order_relaxed) + pixels;
    if (params.timeout_s > 0 && std::chrono::duration<double>(Clock::now() - start).count() >= params.timeout_s)
      throw RenderTimeout(fmt::format("the render did not finish within {} s (--timeout): {} of {} pixels done",
                                      params.timeout_s, done, all_pixels));
  };
  // A stop request seen by trace_ray or between rows says how far the render got.
  auto stopped = [&] {
    return StopError(fmt::format("{}: stopped while rendering ({} of {} pixels done)", stop_message(),
                                 pixels_done.load(std::memory_order_relaxed), all_pixels));
  };
  if (params.mode == RenderMode::kSequential) {
    ShadingScratch scratch;
    try {
      for (int y = 0; y < h; ++y) {
        render_rect(v, ctx, camera, params, 0, y, w, y + 1, result, scratch);
        if (progress) progress->fetch_add(std::uint64_t(w), std::memory_order_relaxed);
        check_time(std::uint64_t(w));
        throw_if_stopped("rendering");
      }
    } catch (const StopError&) {
      throw stopped();
    }
    result.stats = scratch.stats;
    result.stats.traversal = scratch.traversal.stats;
    return result;
  }
  const int ts = params.tile_size;
  const int tx = (w + ts - 1) / ts, ty = (h + ts - 1) / ts;
  tbb::enumerable_thread_specific<ShadingScratch> scratches;
  try {
    tbb::parallel_for(tbb::blocked_range<int>(0, tx * ty, 1), [&](const tbb::blocked_range<int>& range) {
      ShadingScratch& scratch = scratches.local();
      for (int t = range.begin(); t != range.end(); ++t) {
        const int x0 = (t % tx) * ts, y0 = (t / tx) * ts;
        const int x1 = std::min(x0 + ts, w), y1 = std::min(y0 + ts, h);
        render_rect(v, ctx, camera, params, x0, y0, x1, y1, result, scratch);
        if (progress)
          progress->fetch_add(std::uint64_t(x1 - x0) * std::uint64_t(y1 - y0), std::memory_order_relaxed);
        check_time(std::uint64_t(x1 - x0) * std::uint64_t(y1 - y0));
        throw_if_stopped("rendering");
      }
    });
  } catch (const StopError&) {
    throw stopped();
  }
  for (const ShadingScratch& s : scratches) {
    RenderStats part = s.stats;
    part.traversal = s.traversal.stats;
    result.stats += part;
  }
  return result;
}

/// render_image over the plain arrays (DirectView).
RenderResult render(const Database& db, const Grid& grid, const RenderParams& params);

/// The tracer's entry points up to the pixel over one view type `V`
/// (traverse.h's, shade.h's and the pixel's), for explicit instantiation as
/// RAYNODE_TRAVERSAL_INSTANCES: `extern` in V's header, empty in one .cpp.
/// For views whose pixels a node loop drives (svm's paged views).
#define RAYNODE_PIXEL_INSTANCES(EXTERN, V)                                                                   \
  RAYNODE_TRAVERSAL_INSTANCES(EXTERN, V);                                                                    \
  EXTERN template SurfaceFrame surface_frame<V>(const V&, const Primitive&, const Ray&, const Hit&);         \
  EXTERN template Vec3 trace_ray<V>(const V&, const ShadingContext&, const Ray&, int, float, ShadingScratch&, \
                                    FirstHit*, std::uint32_t);                                               \
  EXTERN template PixelResult render_pixel<V>(const V&, const ShadingContext&, const Camera&, int, int, int,  \
                                              bool, ShadingScratch&)

/// RAYNODE_PIXEL_INSTANCES and the whole image's (render_image).
#define RAYNODE_TRACER_INSTANCES(EXTERN, V) \
  RAYNODE_PIXEL_INSTANCES(EXTERN, V);       \
  EXTERN template RenderResult render_image<V>(const V&, const Database&, const RenderParams&)

// The tracer over DirectView is compiled once, in render.cpp.
RAYNODE_TRACER_INSTANCES(extern, DirectView);

}  // namespace raynode::core
