// Reading a scene file's bytes into memory, within limits that always hold.
//
// Place in the data flow: read_nff (nff.h) -> read_scene_text -> the NFF
// parser. A regular file is read in chunks; a FIFO or a character device is
// read without ever blocking for more than a short slice (O_NONBLOCK and
// poll), so that a FIFO with no writer or a silent terminal still honours the
// stop request (core/stop.h, how `--timeout` and signals reach loading). gzip
// data (by its magic bytes, whatever the name) is inflated in chunks. Every
// byte kept counts against one limit, scene_text_limit_bytes(), derived from
// the memory this process may still allocate, never from the file's own
// claims (a gzip size trailer, a device that never ends).
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace raynode::core {

/// The most bytes of scene text (after inflating gzip) read_scene_text keeps
/// by default: a quarter of the smallest of the host's MemAvailable
/// (/proc/meminfo; sysconf(_SC_AVPHYS_PAGES) as a fallback), the address
/// space left under RLIMIT_AS (its soft limit minus VmSize) and the data
/// segment left under RLIMIT_DATA (minus VmData), and at least 16 MiB. The
/// quarter leaves room for the growing text buffer, the compressed input and
/// the scene parsed from the text. Bytes; reads /proc on each call.
std::size_t scene_text_limit_bytes();

/// Reads the whole file at `path` (following symlinks) and inflates it when
/// it starts with the gzip magic (one or more concatenated members).
/// `limit_bytes` bounds the bytes kept: the file's size, the bytes read from
/// a FIFO or device (also at most 1 GiB), and the inflated size. Polls the stop request between
/// chunks (at most every 0.05 s while a FIFO or device is silent).
/// Throws std::runtime_error naming the path: "cannot open/read '...': <OS
/// reason>", "... is a directory", "'...' is N MiB, more than the M MiB ...",
/// "cannot decompress '...': <zlib reason | truncated | more than M MiB>";
/// StopError when a stop was requested.
std::string read_scene_text(const std::string& path, std::size_t limit_bytes = scene_text_limit_bytes());

/// Inflates gzip data held in memory (one or more concatenated members;
/// trailing zeros or garbage after a complete member are ignored, as gzip
/// does). The output grows in 256 KiB chunks and never beyond `limit_bytes`,
/// whatever the size trailers say. `path` names the source in messages.
/// Throws std::runtime_error ("cannot decompress '<path>': ...") or
/// StopError.
std::string gunzip_bytes(std::string_view in, const std::string& path, std::size_t limit_bytes);

/// True when `data` starts with the gzip magic bytes 1f 8b.
bool has_gzip_magic(std::string_view data);

}  // namespace raynode::core
