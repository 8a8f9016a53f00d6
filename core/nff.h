// NFF reader and writer (Neutral File Format, SPD 3.14).
//
// Place in the data flow: file -> read_nff -> Scene -> (make_database, or
// write_nff back to a file). The reader is a token-stream parser, as
// docs/nff.md describes (SPD writes `c` on one line, the
// format document on three). `.nff.gz` is decompressed transparently (zlib).
#pragma once

#include <iosfwd>
#include <stdexcept>
#include <string>
#include <string_view>

#include "core/scene.h"

namespace raynode::core {

/// A malformed scene file. what() is "file:line:col: message" (1-based line
/// and column of the offending token, or of the end of input when truncated).
class ParseError : public std::runtime_error {
 public:
  ParseError(std::string file, int line, int column, const std::string& message);
  const std::string& file() const { return file_; }
  int line() const { return line_; }
  int column() const { return column_; }
  /// The message without the location prefix.
  const std::string& message() const { return message_; }

 private:
  std::string file_;
  int line_;
  int column_;
  std::string message_;
};

/// Reads an NFF scene from `path` (`.nff`, or gzip-compressed: detected by
/// content, so `.nff.gz` works whatever its name; a FIFO or a device is read
/// too: scene_file.h, which also bounds the bytes read). Zero-area polygons
/// are dropped and counted in Scene::dropped_degenerate.
/// Numbers: `#` starts a comment only where a token would start (`1.#INF`
/// is a non-finite number, an error); a decimal too small for float rounds
/// to a denormal or to a signed zero, as IEEE 754 rounding does (1e-400 reads
/// as 0); one too large for float is an error.
/// Throws ParseError on malformed input (unknown keyword, missing or
/// non-finite number, fewer than 3 vertices, a concave polygon of more than
/// kMaxConcavePolygonVertices vertices (database.h), truncated file, a view
/// the camera cannot use: 'at' == 'from', 'up' parallel to the viewing
/// direction, angle outside (0, 180), resolution outside 1..16384),
/// std::runtime_error ("cannot open ...") when the file cannot be read or
/// holds more than the memory limit, StopError when a stop is requested.
Scene read_nff(const std::string& path);

/// Parses NFF text held in memory; `name` is used in error locations. Polls
/// the stop request every 4096 entities and vertices (StopError).
Scene parse_nff(std::string_view text, const std::string& name = "<string>");

/// Writes `scene` as NFF text, in the layout SPD 3.14 writes (`b`, `v` block,
/// lights, then materials and primitives in file order; numbers in `%g`
/// with enough digits to round-trip floats). read_nff(write_nff(s)) == s for
/// every scene read_nff produces.
void write_nff(std::ostream& out, const Scene& scene);

/// Writes to a file; `.gz` suffix writes gzip. Writes to a temporary name
/// and renames, so a failure leaves no half-written file. Throws
/// std::runtime_error on I/O failure.
void write_nff_file(const std::string& path, const Scene& scene);

/// Writes straight into `file_path` (created or truncated; no temporary: the
/// caller owns the file, e.g. a temporary of apps/output_files.h), gzip when
/// `gzip`. Throws std::runtime_error naming `name` (the user's path).
void write_nff_into(const std::string& file_path, const Scene& scene, bool gzip, const std::string& name);

}  // namespace raynode::core
