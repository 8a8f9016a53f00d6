// Reading scene bytes within limits. See scene_file.h for the contract.
#include "core/scene_file.h"

#include <fcntl.h>
#include <poll.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "core/stop.h"

namespace raynode::core {

namespace {

constexpr std::size_t kMiB = std::size_t{1} << 20;
/// Floor of scene_text_limit_bytes(): a tiny headroom reading still works.
constexpr std::size_t kMinTextLimit = 16 * kMiB;
/// Bytes per read() of a file, and per inflate() output chunk.
constexpr std::size_t kReadChunk = std::size_t{1} << 20;
constexpr std::size_t kInflateChunk = std::size_t{256} << 10;
/// Longest a poll() on a FIFO or device waits before the stop request is
/// checked again, milliseconds.
constexpr int kPollSliceMs = 50;
/// The most bytes read from a FIFO or a device (one that never ends, such as
/// /dev/zero, is refused here in about a second, not at the memory limit).
constexpr std::size_t kMaxStreamBytes = std::size_t{1} << 30;

std::string errno_text(int err) { return std::strerror(err); }

/// The "<key>: <n> kB" field of a /proc file in bytes, or SIZE_MAX when absent.
std::size_t proc_kib_field(const char* file, const char* key) {
  std::ifstream in(file);
  std::string line;
  const std::size_t key_len = std::strlen(key);
  while (std::getline(in, line)) {
    if (line.compare(0, key_len, key) != 0 || line.size() <= key_len || line[key_len] != ':') continue;
    const unsigned long long kib = std::strtoull(line.c_str() + key_len + 1, nullptr, 10);
    return kib > std::numeric_limits<std::size_t>::max() / 1024 ? std::numeric_limits<std::size_t>::max()
                                                                : std::size_t(kib) * 1024;
  }
  return std::numeric_limits<std::size_t>::max();
}

/// What is left under a resource limit given the amount in use (SIZE_MAX when unlimited).
std::size_t rlimit_headroom(int resource, std::size_t in_use) {
  rlimit rl{};
  if (getrlimit(resource, &rl) != 0 || rl.rlim_cur == RLIM_INFINITY) return std::numeric_limits<std::size_t>::max();
  const auto cap = static_cast<std::size_t>(rl.rlim_cur);
  if (in_use == std::numeric_limits<std::size_t>::max()) return cap;  // usage unknown: the whole limit
  return cap > in_use ? cap - in_use : 0;
}

std::size_t mib(std::size_t bytes) { return (bytes + kMiB - 1) / kMiB; }

/// Why `limit` bounds scene text, for messages.
const char* kMemoryLimitReason = "the most scene text this process can hold (a quarter of the memory it may still "
                                 "allocate)";

[[noreturn]] void throw_too_large(const std::string& path, const std::string& what, std::size_t limit,
                                  const char* reason = kMemoryLimitReason) {
  throw std::runtime_error(fmt::format("cannot read '{}': {} more than {} MiB, {}", path, what, mib(limit), reason));
}

/// Appends to `out`, growing its capacity by doubling but never past
/// `limit` (the caller has checked that the result fits).
void append_within(std::string& out, const char* p, std::size_t n, std::size_t limit) {
  if (out.size() + n > out.capacity()) out.reserve(std::min(std::max(out.capacity() * 2, out.size() + n), limit));
  out.append(p, n);
}

/// Reads a regular file: its size is known up front, so the limit is
/// checked before anything is allocated.
std::string read_regular(int fd, const std::string& path, std::size_t size, std::size_t limit) {
  if (size > limit) throw_too_large(path, fmt::format("it is {} MiB,", mib(size)), limit);
  const std::string doing = fmt::format("reading '{}'", path);
  std::string data;
  data.reserve(size);
  std::vector<char> chunk(kReadChunk);
  for (;;) {
    throw_if_stopped(doing);
    const ssize_t got = ::read(fd, chunk.data(), chunk.size());
    if (got < 0) {
      if (errno == EINTR || errno == EAGAIN) continue;
      throw std::runtime_error(fmt::format("cannot read '{}': {}", path, errno_text(errno)));
    }
    if (got == 0) break;
    // The file may grow while it is read: the limit still holds.
    if (data.size() + std::size_t(got) > limit) throw_too_large(path, "it holds", limit);
    data.append(chunk.data(), std::size_t(got));
  }
  return data;
}

/// Reads a FIFO or a character device opened with O_NONBLOCK until end of
/// file. poll() waits in short slices so that the stop request is seen
/// within kPollSliceMs. On Linux a FIFO opened for reading before any writer
/// reports no event (not even POLLHUP) until a writer opens it, so waiting
/// for a writer is waiting on poll(); once the last writer closes, read()
/// returns 0 (end of file).
std::string read_stream(int fd, const std::string& path, const char* kind, std::size_t memory_limit) {
  const std::string doing = fmt::format("reading '{}' (a {})", path, kind);
  const bool device_limit = kMaxStreamBytes < memory_limit;
  const std::size_t limit = device_limit ? kMaxStreamBytes : memory_limit;
  std::string data;
  std::vector<char> chunk(kReadChunk);
  for (;;) {
    throw_if_stopped(doing);
    pollfd p{fd, POLLIN, 0};
    const int ready = ::poll(&p, 1, kPollSliceMs);
    if (ready < 0) {
      if (errno == EINTR) continue;
      throw std::runtime_error(fmt::format("cannot read '{}': {}", path, errno_text(errno)));
    }
    if (ready == 0) continue;
    const ssize_t got = ::read(fd, chunk.data(), chunk.size());
    if (got < 0) {
      if (errno == EINTR || errno == EAGAIN) continue;
      throw std::runtime_error(fmt::format("cannot read '{}': {}", path, errno_text(errno)));
    }
    if (got == 0) break;
    if (data.size() + std::size_t(got) > limit) {
      throw_too_large(path, fmt::format("the {} sent", kind), limit,
                      device_limit ? "the most read from a FIFO or a device" : kMemoryLimitReason);
    }
    append_within(data, chunk.data(), std::size_t(got), limit);
  }
  return data;
}

/// Closes a file descriptor on every way out.
struct FdCloser {
  int fd;
  ~FdCloser() {
    if (fd >= 0) ::close(fd);
  }
};

}  // namespace

std::size_t scene_text_limit_bytes() {
  std::size_t avail = proc_kib_field("/proc/meminfo", "MemAvailable");
  if (avail == std::numeric_limits<std::size_t>::max()) {
    const long pages = ::sysconf(_SC_AVPHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
    avail = pages > 0 && page > 0 ? std::size_t(pages) * std::size_t(page) : std::size_t{4} << 30;
  }
  const std::size_t as = rlimit_headroom(RLIMIT_AS, proc_kib_field("/proc/self/status", "VmSize"));
  const std::size_t data = rlimit_headroom(RLIMIT_DATA, proc_kib_field("/proc/self/status", "VmData"));
  return std::max(std::min({avail, as, data}) / 4, kMinTextLimit);
}

bool has_gzip_magic(std::string_view data) {
  return data.size() >= 2 && static_cast<unsigned char>(data[0]) == 0x1f &&
         static_cast<unsigned char>(data[1]) == 0x8b;
}

std::string gunzip_bytes(std::string_view in, const std::string& path, std::size_t limit) {
  z_stream zs{};
  if (inflateInit2(&zs, 15 + 16) != Z_OK) {
    throw std::runtime_error(fmt::format("cannot decompress '{}': zlib init failed", path));
  }
  struct InflateEnd {  // frees zlib's state on every way out
    z_stream* zs;
    ~InflateEnd() { inflateEnd(zs); }
  } end{&zs};
  auto fail = [&](const std::string& why) {
    throw std::runtime_error(fmt::format("cannot decompress '{}': {}", path, why));
  };
  const std::string doing = fmt::format("decompressing '{}'", path);
  std::string out;
  // A first guess from the compressed size, which is real (NFF text
  // compresses about 4-12:1), never from the size trailer, which may lie.
  out.reserve(std::min(limit, in.size() * 8));
  std::vector<char> chunk(kInflateChunk);
  std::size_t in_pos = 0;
  constexpr std::size_t kStep = std::size_t{1} << 30;  // zlib counts input in uInt
  for (;;) {
    throw_if_stopped(doing);
    const std::size_t in_avail = std::min(in.size() - in_pos, kStep);
    zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data() + in_pos));
    zs.avail_in = static_cast<uInt>(in_avail);
    zs.next_out = reinterpret_cast<Bytef*>(chunk.data());
    zs.avail_out = static_cast<uInt>(chunk.size());
    const int rc = inflate(&zs, Z_NO_FLUSH);
    const std::size_t used = in_avail - zs.avail_in;
    const std::size_t produced = chunk.size() - zs.avail_out;
    in_pos += used;
    if (produced > 0) {
      if (produced > limit - out.size()) {
        fail(fmt::format("it inflates to more than {} MiB, {}", mib(limit), kMemoryLimitReason));
      }
      append_within(out, chunk.data(), produced, limit);  // never sized from the trailer
    }
    if (rc == Z_STREAM_END) {
      // Another member may follow (concatenated gzip files).
      if (in_pos + 2 <= in.size() && has_gzip_magic(in.substr(in_pos))) {
        inflateReset(&zs);
        continue;
      }
      break;
    }
    if (rc == Z_BUF_ERROR || (rc == Z_OK && used == 0 && produced == 0)) {
      if (in_pos == in.size() && produced == 0) fail("gzip data is truncated");
      if (used == 0 && produced == 0) fail(zs.msg ? zs.msg : "corrupt gzip data");
      continue;
    }
    if (rc != Z_OK) fail(zs.msg ? zs.msg : "corrupt gzip data");
  }
  return out;
}

std::string read_scene_text(const std::string& path, std::size_t limit) {
  // O_NONBLOCK: opening a FIFO for reading must not wait for a writer (that
  // wait cannot be interrupted by the stop request); regular files ignore it.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) throw std::runtime_error(fmt::format("cannot open '{}': {}", path, errno_text(errno)));
  const FdCloser closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0) throw std::runtime_error(fmt::format("cannot read '{}': {}", path, errno_text(errno)));
  std::string data;
  if (S_ISREG(st.st_mode)) {
    data = read_regular(fd, path, std::size_t(st.st_size), limit);
  } else if (S_ISDIR(st.st_mode)) {
    throw std::runtime_error(fmt::format("cannot read '{}': {}", path, errno_text(EISDIR)));
  } else {
    const char* kind = S_ISFIFO(st.st_mode) ? "FIFO" : S_ISCHR(st.st_mode) ? "character device" : "special file";
    data = read_stream(fd, path, kind, limit);
  }
  if (has_gzip_magic(data)) data = gunzip_bytes(data, path, limit);
  return data;
}

}  // namespace raynode::core
