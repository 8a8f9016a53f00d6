#include "apps/output_files.h"

#include <fcntl.h>
#include <fmt/core.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <climits>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <stdexcept>

#include "apps/commands.h"
#include "imageio/write_image.h"

namespace raynode::apps {

namespace fs = std::filesystem;

// --- The signal-safe list of live temporaries ---------------------------------

namespace {

constexpr std::size_t kMaxTemporaries = 64;
constexpr std::size_t kMaxTemporaryPath = PATH_MAX;

/// A slot's path is written before `live` is set (release) and read by the
/// handler only after it sees `live` (acquire); the owner thread alone
/// claims and frees slots.
struct TemporarySlot {
  std::atomic<bool> live{false};
  char path[kMaxTemporaryPath] = {};
};
std::array<TemporarySlot, kMaxTemporaries> g_temporaries;

/// Puts `path` on the list; returns its slot. Throws std::runtime_error when
/// the list is full or the path too long.
std::size_t register_temporary(const std::string& path) {
  if (path.size() >= kMaxTemporaryPath)
    throw std::runtime_error(fmt::format("cannot write '{}': path too long ({} bytes)", path, path.size()));
  for (std::size_t i = 0; i < g_temporaries.size(); ++i) {
    TemporarySlot& s = g_temporaries[i];
    if (s.live.load(std::memory_order_relaxed)) continue;
    std::memcpy(s.path, path.c_str(), path.size() + 1);
    s.live.store(true, std::memory_order_release);
    return i;
  }
  throw std::runtime_error(fmt::format("cannot write '{}': more than {} outputs at once", path, kMaxTemporaries));
}

void forget_temporary(std::size_t slot) { g_temporaries[slot].live.store(false, std::memory_order_release); }

extern "C" void on_fatal_signal(int sig) {
  remove_temporaries_now();
  const char* line = sig == SIGINT    ? "raynode: stopped by SIGINT (Ctrl-C)\n"
                     : sig == SIGTERM ? "raynode: stopped by SIGTERM\n"
                                      : "raynode: stopped by SIGHUP\n";
  (void)!::write(2, line, std::strlen(line));
  std::signal(sig, SIG_DFL);
  ::raise(sig);
}

}  // namespace

/// A temporary file this process made: on the list while it exists.
class OutputFiles::Temporary {
 public:
  Temporary() = default;
  Temporary(const Temporary&) = delete;
  Temporary& operator=(const Temporary&) = delete;
  ~Temporary() { remove(); }
  /// Creates `path` (O_EXCL, mode 0666 less the umask). Returns errno, 0 on success.
  int create(const std::string& path) {
    slot_ = register_temporary(path);
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0) {
      const int err = errno;
      forget_temporary(slot_);
      slot_ = kNone;
      return err;
    }
    ::close(fd);
    path_ = path;
    return 0;
  }
  const std::string& path() const { return path_; }
  bool exists() const { return slot_ != kNone; }
  /// The file was renamed away: nothing to remove any more.
  void release() {
    if (slot_ != kNone) forget_temporary(slot_);
    slot_ = kNone;
  }
  void remove() {
    if (slot_ == kNone) return;
    ::unlink(path_.c_str());
    release();
  }

 private:
  static constexpr std::size_t kNone = std::size_t(-1);
  std::size_t slot_ = kNone;
  std::string path_;
};

void remove_temporaries_now() noexcept {
  for (TemporarySlot& s : g_temporaries)
    if (s.live.load(std::memory_order_acquire)) ::unlink(s.path);
}

void install_cleanup_handlers() {
  static bool installed = false;
  if (installed) return;
  installed = true;
  struct sigaction sa {};
  sa.sa_handler = on_fatal_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESETHAND;
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
    // A signal ignored at start (nohup, a shell's background job) stays ignored.
    struct sigaction old {};
    if (::sigaction(sig, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;
    ::sigaction(sig, &sa, nullptr);
  }
}

// --- Resolving a path ---------------------------------------------------------

namespace {

std::string os_reason(int err) { return std::strerror(err); }

/// The descriptor a path names as a stream: "-" and /dev/stdout are 1,
/// /dev/stderr 2, /dev/fd/N and /proc/self/fd/N are N; -1 otherwise.
int descriptor_of(const std::string& path) {
  if (path == "-" || path == "/dev/stdout") return 1;
  if (path == "/dev/stderr") return 2;
  for (const char* prefix : {"/dev/fd/", "/proc/self/fd/"}) {
    const std::string p(prefix);
    if (path.compare(0, p.size(), p) != 0 || path.size() == p.size() || path.size() > p.size() + 6) continue;
    int n = 0;
    for (std::size_t i = p.size(); i < path.size(); ++i) {
      if (path[i] < '0' || path[i] > '9') return -1;
      n = n * 10 + (path[i] - '0');
    }
    return n;
  }
  return -1;
}

/// Follows symlinks from `path` to the file they name (which may not exist
/// yet). Throws std::runtime_error on a loop.
std::string follow_links(const std::string& path, const std::string& what) {
  fs::path p(path);
  for (int hops = 0; hops < 40; ++hops) {
    struct stat st {};
    if (::lstat(p.c_str(), &st) != 0 || !S_ISLNK(st.st_mode)) return p.string();
    std::error_code ec;
    const fs::path next = fs::read_symlink(p, ec);
    if (ec) throw std::runtime_error(fmt::format("cannot write {} '{}': {}", what, path, ec.message()));
    p = next.is_absolute() ? next : p.parent_path() / next;
  }
  throw std::runtime_error(fmt::format("cannot write {} '{}': {}", what, path, os_reason(ELOOP)));
}

/// Who a path is: device and inode when it exists, and its normalised
/// absolute path (symlinks in the existing part resolved) in any case.
struct FileIdentity {
  bool exists = false;
  dev_t dev = 0;
  ino_t ino = 0;
  std::string normal;
  bool same_as(const FileIdentity& o) const {
    if (exists && o.exists) return dev == o.dev && ino == o.ino;
    return normal == o.normal;
  }
};

FileIdentity identify(const std::string& path) {
  FileIdentity id;
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) {
    id.exists = true;
    id.dev = st.st_dev;
    id.ino = st.st_ino;
  }
  std::error_code ec;
  fs::path n = fs::weakly_canonical(fs::absolute(path, ec), ec);
  id.normal = (ec ? fs::absolute(path).lexically_normal() : n).string();
  return id;
}

/// /dir/o.png -> /dir/.raynode-<pid>-<k>.part: short, so that it fits
/// wherever the final name fits.
std::string temporary_beside(const std::string& target, std::size_t k) {
  const fs::path dir = fs::path(target).parent_path();
  const std::string name = fmt::format(".raynode-{}-{}.part", ::getpid(), k);
  return (dir.empty() ? fs::path(name) : dir / name).string();
}

void write_all(int fd, const char* p, std::size_t n, const std::string& path) {
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      throw std::runtime_error(fmt::format("cannot write '{}': {}", path, os_reason(errno)));
    }
    p += w;
    n -= std::size_t(w);
  }
}

/// Copies the file at `from` into the open descriptor `fd`.
void copy_into(const std::string& from, int fd, const std::string& path) {
  const int in = ::open(from.c_str(), O_RDONLY | O_CLOEXEC);
  if (in < 0) throw std::runtime_error(fmt::format("cannot write '{}': {}", path, os_reason(errno)));
  char buf[1 << 16];
  for (;;) {
    const ssize_t r = ::read(in, buf, sizeof buf);
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) {
      const int err = errno;
      ::close(in);
      throw std::runtime_error(fmt::format("cannot write '{}': {}", path, os_reason(err)));
    }
    if (r == 0) break;
    try {
      write_all(fd, buf, std::size_t(r), path);
    } catch (...) {
      ::close(in);
      throw;
    }
  }
  ::close(in);
}

}  // namespace

// --- OutputFiles ----------------------------------------------------------------

OutputFiles::Out::Out() = default;
OutputFiles::Out::Out(Out&&) noexcept = default;
OutputFiles::Out::~Out() = default;

OutputFiles::OutputFiles(std::vector<std::string> inputs) : inputs_(std::move(inputs)) {}

OutputFiles::~OutputFiles() = default;

bool OutputFiles::uses_stdout() const {
  for (const Out& o : outs_)
    if (o.kind == Kind::kDescriptor && o.fd == 1) return true;
  return false;
}

std::size_t OutputFiles::add(const std::string& path, const std::string& what, bool text) {
  if (path.empty()) throw UsageError(fmt::format("the {} path is empty", what));
  Out o;
  o.path = path;
  o.what = what;
  o.temp = std::make_unique<Temporary>();
  if (const int fd = descriptor_of(path); fd >= 0) {
    if (!text)
      throw UsageError(fmt::format("the {} cannot go to '{}' (a stream): give a file name with an extension", what,
                                   path));
    for (const Out& other : outs_)
      if (other.kind == Kind::kDescriptor && other.fd == fd)
        throw UsageError(fmt::format("the {} and the {} would both go to '{}'; give one a file name", other.what,
                                     what, path));
    if (::fcntl(fd, F_GETFD) < 0)
      throw std::runtime_error(fmt::format("cannot write {} '{}': descriptor {} is not open", what, path, fd));
    o.kind = Kind::kDescriptor;
    o.fd = fd;
    outs_.push_back(std::move(o));
    return outs_.size() - 1;
  }

  o.target = follow_links(path, what);
  auto fail = [&](const std::string& why) {
    throw std::runtime_error(fmt::format("cannot write {} '{}': {}", what, path, why));
  };
  struct stat st {};
  const bool exists = ::stat(o.target.c_str(), &st) == 0;
  if (exists) {
    if (S_ISDIR(st.st_mode)) fail("a directory is in the way");
    if (S_ISFIFO(st.st_mode) || S_ISCHR(st.st_mode)) o.kind = Kind::kStream;
    else if (!S_ISREG(st.st_mode)) fail("it is neither a regular file, a FIFO nor a character device");
    if (::access(o.target.c_str(), W_OK) != 0) fail(os_reason(errno));
  } else {
    const fs::path dir = fs::path(o.target).parent_path();
    std::error_code ec;
    if (!dir.empty() && !fs::is_directory(dir, ec))
      fail(fmt::format("directory '{}' does not exist", dir.string()));
  }

  // Not an input, not another output.
  const FileIdentity id = identify(o.target);
  for (const std::string& in : inputs_) {
    if (in.empty() || descriptor_of(in) >= 0) continue;
    struct stat ist {};
    if (::stat(in.c_str(), &ist) != 0) continue;
    if (id.same_as(identify(in)))
      throw UsageError(fmt::format("the {} '{}' is the input scene '{}'; writing it would destroy the scene", what,
                                   path, in));
  }
  for (const Out& other : outs_) {
    if (other.kind == Kind::kDescriptor) continue;
    if (id.same_as(identify(other.target)))
      throw UsageError(fmt::format("the {} '{}' and the {} '{}' are the same file; give them different paths",
                                   other.what, other.path, what, path));
  }

  if (o.kind == Kind::kFile) {
    // The final name must fit the directory's file system, which the short
    // temporary does not prove.
    const fs::path dir = fs::path(o.target).parent_path();
    const std::string name = fs::path(o.target).filename().string();
    const long name_max = ::pathconf(dir.empty() ? "." : dir.c_str(), _PC_NAME_MAX);
    if (name_max > 0 && long(name.size()) > name_max)
      fail(fmt::format("{} (the name has {} bytes, this file system allows {})", os_reason(ENAMETOOLONG),
                       name.size(), name_max));
    if (name.empty() || name == "." || name == "..") fail("not a file name");
    const int err = o.temp->create(temporary_beside(o.target, outs_.size()));
    if (err != 0) fail(os_reason(err));
    o.mode = exists ? (st.st_mode & 07777) : -1;
  }
  outs_.push_back(std::move(o));
  return outs_.size() - 1;
}

void OutputFiles::open_scratch(Out& o) {
  if (o.temp->exists()) return;
  std::error_code ec;
  fs::path dir = fs::temp_directory_path(ec);
  if (ec) dir = "/tmp";
  for (int attempt = 0; attempt < 100; ++attempt) {
    const std::string p = (dir / fmt::format("raynode-{}-{}-{}.part", ::getpid(), &o - outs_.data(), attempt)).string();
    const int err = o.temp->create(p);
    if (err == 0) return;
    if (err != EEXIST)
      throw std::runtime_error(fmt::format("cannot write {} '{}': no scratch file in '{}': {}", o.what, o.path,
                                           dir.string(), os_reason(err)));
  }
  throw std::runtime_error(fmt::format("cannot write {} '{}': no scratch file in '{}'", o.what, o.path, dir.string()));
}

void OutputFiles::image(std::size_t id, const core::Image& image) {
  file(id, [&](const std::string& file_path) { imageio::write_image_as(outs_[id].path, file_path, image); });
}

void OutputFiles::text(std::size_t id, const std::string& text) {
  Out& o = outs_.at(id);
  if (o.kind != Kind::kFile) {
    o.data = text;
    o.written = true;
    return;
  }
  file(id, [&](const std::string& file_path) {
    const int fd = ::open(file_path.c_str(), O_WRONLY | O_TRUNC | O_CLOEXEC);
    if (fd < 0) throw std::runtime_error(fmt::format("cannot write '{}': {}", o.path, os_reason(errno)));
    try {
      write_all(fd, text.data(), text.size(), o.path);
    } catch (...) {
      ::close(fd);
      throw;
    }
    if (::close(fd) != 0) throw std::runtime_error(fmt::format("cannot write '{}': {}", o.path, os_reason(errno)));
  });
}

void OutputFiles::file(std::size_t id, const std::function<void(const std::string&)>& write) {
  Out& o = outs_.at(id);
  if (o.kind != Kind::kFile) open_scratch(o);
  write(o.temp->path());
  o.in_scratch = o.kind != Kind::kFile;
  o.written = true;
}

void OutputFiles::update(std::size_t id, const std::string& text) {
  Out& o = outs_.at(id);
  this->text(id, text);
  if (o.kind != Kind::kFile) return;
  const std::string tmp = o.temp->path();
  if (o.mode >= 0) ::chmod(tmp.c_str(), mode_t(o.mode));
  if (::rename(tmp.c_str(), o.target.c_str()) != 0)
    throw std::runtime_error(fmt::format("cannot write {} '{}': {}", o.what, o.path, os_reason(errno)));
  o.temp->release();
  o.written = false;
  if (const int err = o.temp->create(tmp); err != 0)
    throw std::runtime_error(fmt::format("cannot write {} '{}': {}", o.what, o.path, os_reason(err)));
}

void OutputFiles::commit() {
  // Regular files first (a rename each), then streams, whose writes may
  // wait for a reader.
  for (Out& o : outs_) {
    if (!o.written || o.kind != Kind::kFile) continue;
    if (o.mode >= 0) ::chmod(o.temp->path().c_str(), mode_t(o.mode));
    if (::rename(o.temp->path().c_str(), o.target.c_str()) != 0)
      throw std::runtime_error(fmt::format("cannot write {} '{}': {}", o.what, o.path, os_reason(errno)));
    o.temp->release();
  }
  for (Out& o : outs_) {
    if (!o.written || o.kind == Kind::kFile) continue;
    int fd = o.fd;
    if (o.kind == Kind::kStream) {
      fd = ::open(o.target.c_str(), O_WRONLY | O_CLOEXEC);
      if (fd < 0) throw std::runtime_error(fmt::format("cannot write {} '{}': {}", o.what, o.path, os_reason(errno)));
    } else {
      std::fflush(fd == 1 ? stdout : stderr);
    }
    try {
      if (o.in_scratch) copy_into(o.temp->path(), fd, o.path);
      else write_all(fd, o.data.data(), o.data.size(), o.path);
    } catch (...) {
      if (o.kind == Kind::kStream) ::close(fd);
      throw;
    }
    if (o.kind == Kind::kStream && ::close(fd) != 0)
      throw std::runtime_error(fmt::format("cannot write {} '{}': {}", o.what, o.path, os_reason(errno)));
    o.temp->remove();
  }
  outs_.clear();
}

}  // namespace raynode::apps
