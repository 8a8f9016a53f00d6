// The files a command writes (image, AOVs, maps, --stats JSON, CSVs, NFF),
// made safe against losing data.
//
// Place in the data flow: a command declares every output before any work
// (OutputFiles::add), fills them once its results exist (image, text, or a
// writer callback), and commits them together at the end. What add() does:
//   - refuses an output that is the command's input or another output:
//     by device and inode for existing files, by normalised path for new
//     ones (UsageError, exit 2);
//   - "-", /dev/stdout, /dev/stderr and /dev/fd/N are those streams (text
//     outputs only);
//   - a symlink is followed: its target is written (the link stays);
//   - a FIFO or a character device is written into directly at commit;
//   - a regular file (or a new one) is written to a temporary beside it,
//     created here with O_EXCL, so that an unwritable place fails before
//     the work, with the user's path and the OS reason (exit 1); commit()
//     renames it into place, so a failed or interrupted run leaves the old
//     file, never a partial one;
//   - a directory, socket or block device is refused.
// Temporaries are on a signal-safe list: SIGINT, SIGTERM and SIGHUP remove
// them before the process dies (install_cleanup_handlers), as does the
// --timeout watchdog (apps/watchdog.h).
#pragma once

#include <cstdio>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/image.h"

namespace raynode::apps {

/// Installs the SIGINT/SIGTERM/SIGHUP handlers that remove every live
/// temporary and then die of the same signal (exit status 128+N).
/// Idempotent; call once from main.
void install_cleanup_handlers();

/// Removes every live temporary. Async-signal-safe (unlink only).
void remove_temporaries_now() noexcept;

/// One command's outputs, committed together. Owner thread only.
class OutputFiles {
 public:
  /// `inputs`: files the command reads (the scene); an output may not be
  /// one of them. Paths that do not exist are ignored.
  explicit OutputFiles(std::vector<std::string> inputs = {});
  OutputFiles(const OutputFiles&) = delete;
  OutputFiles& operator=(const OutputFiles&) = delete;
  /// Removes the temporaries of anything not committed.
  ~OutputFiles();

  /// Declares an output; call before the work. `what` names it in messages
  /// ("image", "--stats file", "CSV"). `text`: the output may be a stream
  /// ("-" = stdout). Throws UsageError (exit 2) when `path` is an input,
  /// another output, or "-" for a binary output; std::runtime_error (exit 1)
  /// naming `path` and the reason when it cannot be written (missing or
  /// read-only directory, name too long, a directory or socket in the way).
  /// Returns the output's index.
  std::size_t add(const std::string& path, const std::string& what, bool text = true);

  /// Writes `image` for output `id` (format by the extension of its path;
  /// imageio::write_image_as's conversions). Throws std::runtime_error.
  void image(std::size_t id, const core::Image& image);
  /// Writes `text` for output `id`. Throws std::runtime_error.
  void text(std::size_t id, const std::string& text);
  /// Lets `write(file_path)` write output `id` to a file path (a temporary
  /// or a scratch file); its format is the final path's (see final_path).
  void file(std::size_t id, const std::function<void(const std::string& file_path)>& write);

  /// Puts `text` in place as output `id` now, as commit() would, and keeps
  /// the output open for later versions: a long command's CSV that holds
  /// every finished point if the command is interrupted. A regular file is
  /// replaced whole (never partly written); a stream gets only the version
  /// committed at the end. Throws std::runtime_error.
  void update(std::size_t id, const std::string& text);

  /// The user's path of output `id`, as given.
  const std::string& path(std::size_t id) const { return outs_[id].path; }
  /// True when some output goes to stdout (then a command prints its
  /// summary to stderr, so the two do not mix).
  bool uses_stdout() const;

  /// Puts every written output in place: renames the temporaries, copies
  /// stream outputs into their FIFOs, devices or descriptors. An output
  /// declared but not written is dropped (its temporary removed). Throws
  /// std::runtime_error naming the user's path and the reason; outputs
  /// already in place stay (each is whole), the others keep their old
  /// content.
  void commit();

 private:
  enum class Kind { kFile, kStream, kDescriptor };
  class Temporary;  ///< a temporary file on the signal-safe list
  struct Out {
    std::string path;  ///< as the user gave it
    std::string what;
    Kind kind = Kind::kFile;
    std::string target;  ///< kFile: the file replaced (symlinks followed); kStream: the FIFO or device
    int fd = -1;         ///< kDescriptor: 1, 2, or N of /dev/fd/N
    int mode = -1;       ///< kFile: the replaced file's permission bits, kept; -1 for a new file
    std::unique_ptr<Temporary> temp;  ///< kFile: beside target; others: a scratch file for image()/file()
    bool written = false;
    bool in_scratch = false;  ///< a stream's content is in `temp`, not in `data`
    std::string data;         ///< a stream's text
    Out();
    Out(Out&&) noexcept;
    ~Out();
  };
  void open_scratch(Out& o);
  std::vector<std::string> inputs_;
  std::vector<Out> outs_;
};

}  // namespace raynode::apps
