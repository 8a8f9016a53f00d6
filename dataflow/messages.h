// Messages of the data-oriented mode (docs/architecture.md, "dataflow"; CONVENTIONS:
// plain trivially copyable structs with ids, never pointers). Wire size =
// the payload's size.
//
// Place in the data flow: a node's ray leaving its region -> RayMsg (kRay)
// -> the next region's owner, or the host when that owner's mailbox is full
// (spill) -> the host forwards it later; finished pixel terms ->
// ContributionBatch (kContribution) -> host frame buffer; termination waves
// -> TokenMsg (kToken) host <-> nodes; kShutdown ends the frame.
#pragma once

#include <cstdint>
#include <type_traits>

#include "core/database.h"

namespace raynode::dataflow {

/// Kinds of ray, as counted (the paper's primary, shadow, reflected, refracted).
enum class RayKind : std::uint8_t { kPrimary = 0, kShadow = 1, kReflected = 2, kRefracted = 3 };
inline constexpr int kRayKindCount = 4;
/// "primary", "shadow", "reflected", "refracted".
const char* ray_kind_name(RayKind kind);

/// RayMsg::flags bits.
inline constexpr std::uint8_t kRayFirstHit = 1;      ///< primary through the pixel centre: report its first hit (AOVs)
inline constexpr std::uint8_t kRayProbeOnly = 2;     ///< AOV-only primary (even spp): no shading
/// Shadow ray whose highlight is skipped (the Shine marker): counted, as
/// core::trace_ray does, only when the ray reaches the light.
inline constexpr std::uint8_t kRayHighlightSkip = 4;

/// A ray on its way: the ray (origin, direction; tmin is 0, or for an eye
/// ray the view's hither distance, which every node's camera holds), where
/// it enters the destination region, its path weight and, for a shadow
/// ray, the pixel term it carries if it reaches the light.
struct RayMsg {
  float origin[3];     ///< world units
  float direction[3];  ///< not necessarily unit (shadow rays: to the light, tmax 1)
  float tmax;          ///< end of the ray, clipped to the scene box
  float t_enter;       ///< ray parameter where it enters `region`
  float weight;        ///< path weight: product of Ks / T factors from the eye ray (1)
  float color[3];      ///< shadow ray: its term of the pixel (already times weight), added if unblocked
  std::uint32_t pixel; ///< y * width + x
  std::uint32_t region;  ///< destination region
  RayKind kind;
  std::uint8_t depth;  ///< ray level, eye ray = 1
  std::uint8_t flags;
  std::uint8_t reserved0 = 0;
  /// The triangle the ray leaves (core::SurfaceFrame::leaving), by its id in
  /// the region that spawned the ray, whose query skips it; core::kNoPrimitive
  /// for eye rays and once the ray is in another region (ids are local).
  std::uint32_t origin_triangle = core::kNoPrimitive;
};
static_assert(std::is_trivially_copyable_v<RayMsg>);
static_assert(sizeof(RayMsg) == 64);

/// Header of a kContribution message: `count` records of `kind` follow.
struct ContributionHeader {
  std::uint32_t kind;   ///< 0: Contribution records, 1: FirstHitRecord records
  std::uint32_t count;
};
/// A term of a pixel's colour (before the 1/spp^2 average).
struct Contribution {
  std::uint32_t pixel;
  float rgb[3];
};
/// First hit of a pixel's centre ray (AOVs).
struct FirstHitRecord {
  std::uint32_t pixel;
  std::int32_t shape;   ///< NFF shape index
  std::uint32_t region; ///< region the hit lies in
  float t;              ///< distance along the unit eye ray
  float normal[3];      ///< shading normal, face-forwarded
};
static_assert(std::is_trivially_copyable_v<ContributionHeader> && std::is_trivially_copyable_v<Contribution> &&
              std::is_trivially_copyable_v<FirstHitRecord>);

/// Termination wave (kToken): the host's probe carries the wave; a node's
/// answer (sent when it is passive) adds its counts of work messages.
struct TokenMsg {
  std::uint32_t wave;
  std::uint32_t reserved = 0;
  std::uint64_t sent;      ///< work messages (rays, contribution batches) sent so far
  std::uint64_t received;  ///< work messages received so far
};
static_assert(std::is_trivially_copyable_v<TokenMsg>);

}  // namespace raynode::dataflow
