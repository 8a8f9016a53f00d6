// Regions of the data-oriented mode: the scene extent cut into 3D regions by
// median planes perpendicular to the screen's x and y axes (paper, "Static
// load balancing", Figure 2b), and the geometry every node needs to move a
// ray from region to region (docs/architecture.md, "dataflow").
//
// Place in the data flow: estimate.h's CostGrid -> make_partition -> a
// Partition (kd-tree of cuts + one ScreenRect per region) -> the host picks
// each region's primitives (region_view.h) and gives every node a copy of
// the kd-tree (RegionMap over arena arrays) -> nodes call first_region /
// exit_region for every ray.
//
// Representation. A region is a prism along the view direction: an
// axis-aligned rectangle in the camera's screen-aligned frame (CameraFrame:
// x = dot(p - from, u), y = dot(p - from, v), u = screen right, v = screen
// up, as in core::Camera), unbounded along the view axis w. The rectangles
// of the outermost regions extend to +-infinity, so every point of space
// lies in exactly one region. A ray (o, d) is followed in its own affine
// screen coordinates x(t) = x0 + t dx, y(t) = y0 + t dy, with x0, dx (y0,
// dy) computed once from the message's floats by the same expression on
// every node; its parameter range is cut into half-open intervals
// [t_enter, t_exit), one per region visited, and the t_exit of one region is
// passed on as the t_enter of the next, so the intervals of one ray never
// overlap and never leave a gap, whatever rounding does. A point exactly on
// a cut belongs to the side the ray moves to (the upper side when the ray is
// parallel to the cut). Hits are accepted by t (node_tracer.cpp), never by a
// point-in-region test, so each hit is taken by exactly one region.
//
// Regions are numbered in the kd-tree's left-to-right order; region i is
// owned by node i. With the recursive halving, the two halves of every cut
// are the two halves of the id range, so on a hypercube of 2^k nodes the
// regions on either side of the last cuts differ in one id bit: neighbours
// in space are neighbours in the network (the paper's mapping of the
// connectivity graph, Figure 3).
#pragma once

#include <cmath>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "core/math.h"
#include "core/scene.h"

namespace raynode::dataflow {

/// The camera's orthonormal frame (same vectors as core::Camera).
struct CameraFrame {
  core::Vec3 origin;  ///< the eye (view.from)
  core::Vec3 u;       ///< screen right, unit
  core::Vec3 v;       ///< screen up, unit
  core::Vec3 w;       ///< viewing direction, unit

  /// Frame of a view; throws std::invalid_argument like core::Camera.
  static CameraFrame of(const core::View& view);
  float x(const core::Vec3& p) const { return core::dot(p - origin, u); }
  float y(const core::Vec3& p) const { return core::dot(p - origin, v); }
  float z(const core::Vec3& p) const { return core::dot(p - origin, w); }
};

/// A rectangle in screen-frame coordinates [x0, x1) x [y0, y1), world units;
/// infinite sides allowed.
struct ScreenRect {
  float x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  float lo(int axis) const { return axis == 0 ? x0 : y0; }
  float hi(int axis) const { return axis == 0 ? x1 : y1; }
};

/// One node of the kd-tree: an inner node cuts `axis` (0 = screen x, 1 =
/// screen y) at `cut`; a leaf (axis < 0) is region `child[0]`.
struct KdNode {
  std::int32_t axis = -1;
  float cut = 0;
  std::int32_t child[2] = {0, 0};  ///< inner: indices of the lower / upper side's nodes
};

/// A ray in screen coordinates: x(t) = x0 + t dx, y(t) = y0 + t dy.
struct ScreenRay {
  float x0, dx, y0, dy;
  static ScreenRay of(const CameraFrame& f, const core::Vec3& origin, const core::Vec3& direction) {
    return {f.x(origin), core::dot(direction, f.u), f.y(origin), core::dot(direction, f.v)};
  }
};

/// What a node needs to route rays: the frame, the kd-tree and the regions'
/// ownership rectangles. Refers to (does not own) its arrays — the host's
/// Partition or a node's arena copies. Read-only, any thread.
struct RegionMap {
  CameraFrame frame;
  std::span<const KdNode> tree;      ///< root at index 0
  std::span<const ScreenRect> rects;  ///< per region, outer sides infinite

  std::uint32_t region_count() const { return std::uint32_t(rects.size()); }
  /// The region owning screen point (x, y) for a ray moving along (dx, dy)
  /// (ties on a cut go to the side the ray moves to, the upper side if none).
  std::uint32_t locate(float x, float y, float dx, float dy) const;
  /// The region a ray is in at parameter t.
  std::uint32_t region_at(const ScreenRay& r, float t) const {
    return locate(r.x0 + t * r.dx, r.y0 + t * r.dy, r.dx, r.dy);
  }
  /// Where the ray leaves `region` after entering it at t_enter: returns
  /// t_exit >= t_enter (+inf if never) and sets `next` to the region it
  /// enters there (a face or corner neighbour; unchanged when t_exit is
  /// infinite).
  float exit_region(std::uint32_t region, const ScreenRay& r, float t_enter, std::uint32_t& next) const;
};

/// The partition of the scene extent into regions.
struct Partition {
  CameraFrame frame;
  ScreenRect extent;               ///< the scene's bounds projected on the screen frame
  std::vector<KdNode> tree;        ///< root at 0
  std::vector<ScreenRect> rects;   ///< per region: ownership rectangle (outer sides infinite)
  std::vector<ScreenRect> finite;  ///< per region: rectangle clipped to `extent`

  std::uint32_t region_count() const { return std::uint32_t(rects.size()); }
  RegionMap map() const { return {frame, tree, rects}; }
};

/// Screen extent of a world box under `frame` (its 8 corners projected),
/// padded by 1e-4 of its size so that nothing lies on its border.
ScreenRect screen_extent(const CameraFrame& frame, const core::Bounds3& bounds);

/// Cost per cell of a 2D grid of nx x ny equal cells over `extent`,
/// row-major (index y * nx + x, y growing with screen y). Any unit.
struct CostGrid {
  ScreenRect extent;
  int nx = 1, ny = 1;
  std::vector<double> cost;
  double total() const;
};

/// Recursive median cuts on `cost`, alternating screen x and y from the
/// root, into exactly `regions` regions (>= 1; any count: a part of n
/// regions is cut so that its lower side gets floor(n/2)/n of its cost).
/// The cut lies inside a cell by linear interpolation (cost spread evenly
/// over the cell); a part without cost is cut by length. With a uniform
/// cost (or `equal`) the regions have equal size. Throws
/// std::invalid_argument for 0 regions or an empty grid.
Partition make_partition(const CameraFrame& frame, const CostGrid& cost, std::uint32_t regions);

/// Cost of `cost` inside a rectangle (cells partly covered count by area).
double cost_in(const CostGrid& cost, const ScreenRect& rect);

}  // namespace raynode::dataflow
