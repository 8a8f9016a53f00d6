// Image output through OpenImageIO.
//
// Place in the data flow: core::Image (render.h) -> write_image_as -> a file
// whose format OpenImageIO picks from the extension (.png, .exr, .tif,
// .ppm, .jpg, ...).
#pragma once

#include <string>

#include "core/image.h"

namespace raynode::imageio {

/// True when the extension of `path` names a float (HDR) format: .exr, .hdr.
bool is_float_format(const std::string& path);

/// True when OpenImageIO has a writer for the extension of `path`.
bool can_write_format(const std::string& path);

/// Writes `image` (linear floats, 1 or 3 channels) to `file_path` in the
/// format that the extension of `format_path` names. Float formats (.exr,
/// .hdr) get the floats unchanged (EXR: 32-bit float); every other format
/// gets 8 bits per channel, each value clamped to [0, 1], times 255, rounded
/// to nearest. Written straight into
/// `file_path` (no temporary: the caller owns the file, e.g. a temporary of
/// apps/output_files.h). Throws std::runtime_error naming `format_path`.
void write_image_as(const std::string& format_path, const std::string& file_path, const core::Image& image);

}  // namespace raynode::imageio
