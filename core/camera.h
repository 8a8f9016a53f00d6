// Pinhole camera from the NFF view block (docs/nff.md,
// "The view block"): w = normalize(at - from), u = normalize(w x up)
// (screen right), v = u x w (screen up), right-handed. `angle` is the full
// field of view between the centres of the first and last pixel columns;
// pixels are square, so the vertical spacing equals the horizontal one.
//
// Place in the data flow: Database::view (+ --width/--height) -> Camera ->
// primary rays for every mode.
#pragma once

#include <cmath>
#include <stdexcept>

#include "core/math.h"
#include "core/scene.h"

namespace raynode::core {

/// True when `up` has a direction and is not parallel to the unit viewing
/// direction `w`: |w x up/|up|| > 1e-6 (the sine of their angle), with up
/// normalised first so that no length of up overflows or underflows the
/// test (`up 0 1e20 0` is as good as `up 0 1 0`). The NFF reader applies the
/// same test, so a view it accepts always renders.
inline bool up_is_usable(const Vec3& w, const Vec3& up) {
  if (!is_finite(up) || !(max_component(abs(up)) > 0.0f)) return false;
  return length(cross(w, normalize_any(up))) > 1e-6f;
}

class Camera {
 public:
  /// Throws std::invalid_argument when from == at, up is parallel to the
  /// view direction, the angle is not in (0, 180) degrees, or the
  /// resolution is not positive.
  Camera(const View& view, int width, int height) : origin_(view.from), width_(width), height_(height) {
    if (width < 1 || height < 1)
      throw std::invalid_argument("image resolution must be positive, got " + std::to_string(width) + "x" +
                                  std::to_string(height));
    const Vec3 dir = view.at - view.from;
    if (!(dot(dir, dir) > 0.0f)) throw std::invalid_argument("view 'from' and 'at' are the same point");
    w_ = normalize_any(dir);  // also when 'from' is farther than ~1.8e19 from 'at'
    if (!up_is_usable(w_, view.up)) throw std::invalid_argument("view 'up' is parallel to the viewing direction");
    // w x up as given (bit-identical to earlier releases for ordinary
    // lengths of up); from the unit up when that product overflows.
    const Vec3 right = cross(w_, view.up);
    u_ = is_finite(right) ? normalize_any(right) : normalize(cross(w_, normalize_any(view.up)));
    v_ = cross(u_, w_);
    hither_ = std::isfinite(view.hither) && view.hither > 0.0f ? view.hither : 0.0f;
    if (!(view.angle > 0.0f && view.angle < 180.0f))
      throw std::invalid_argument("view angle must be in (0, 180) degrees");
    const double half = std::tan(double(view.angle) * 3.14159265358979323846 / 360.0);
    const int n = width > 1 ? width - 1 : 1;
    spacing_ = float(2.0 * half / n);
  }

  /// Ray through image position (px, py) in pixels: (0,0) is the top-left
  /// corner of the image, (i + 0.5, j + 0.5) the centre of pixel column i,
  /// row j. The direction is unit length; tmin is the view's hither
  /// distance (world units along the ray; 0 when the view gives none): eye
  /// rays start at the eye, never at an offset of their own.
  Ray ray_through(float px, float py) const {
    const float x = (px - 0.5f * float(width_)) * spacing_;
    const float y = (0.5f * float(height_) - py) * spacing_;
    return Ray{origin_, normalize(w_ + u_ * x + v_ * y), hither_, kInfinity};
  }

  /// Start of every eye ray, world units along the (unit) ray.
  float hither() const { return hither_; }

  int width() const { return width_; }
  int height() const { return height_; }
  const Vec3& origin() const { return origin_; }

 private:
  Vec3 origin_, u_, v_, w_;
  float spacing_ = 0.0f;
  float hither_ = 0.0f;
  int width_, height_;
};

}  // namespace raynode::core
