// False-colour pictures of per-pixel counts and labels, for the PNG maps of
// the node modes' AOVs: a heat map of svm's pages per pixel (the paper's
// Table 2 quantity, seen per pixel) and a label map of which node computed
// each pixel (the paper's Figure 6).
//
// Place in the data flow: a 1-channel core::Image (counts, ids) ->
// heat_map / label_map -> 3-channel image in [0, 1] -> write_image (.png).
#pragma once

#include "core/image.h"

namespace raynode::imageio {

/// Maps each value v of a 1-channel image to a colour ramp (black, blue,
/// magenta, orange, yellow, white) over [0, max]: max = the image's largest
/// value when `max` <= 0. Returns a 3-channel image of the same size.
core::Image heat_map(const core::Image& values, float max = 0);

/// Gives each integer label of a 1-channel image its own colour (golden-
/// ratio hues, so neighbouring ids differ); negative labels are black.
core::Image label_map(const core::Image& labels);

}  // namespace raynode::imageio
