// apps/output_files.h: outputs that never lose data.
#include "apps/output_files.h"

#include <doctest/doctest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "apps/commands.h"

namespace fs = std::filesystem;
using raynode::apps::OutputFiles;
using raynode::apps::UsageError;

namespace {

/// A fresh empty directory under the system's temporary directory.
struct ScratchDir {
  fs::path path;
  ScratchDir() {
    path = fs::temp_directory_path() / ("raynode-output-files-test-" + std::to_string(::getpid()));
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~ScratchDir() { fs::remove_all(path); }
  std::string at(const std::string& name) const { return (path / name).string(); }
  /// Names in the directory, sorted, joined by spaces.
  std::string listing() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(path)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    std::string out;
    for (const std::string& n : names) out += (out.empty() ? "" : " ") + n;
    return out;
  }
};

std::string read(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

void write(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

}  // namespace

TEST_CASE("output files: an output that is the input or another output is refused, and nothing is touched") {
  ScratchDir d;
  write(d.at("scene.nff"), "precious scene");
  write(d.at("o.json"), "precious");
  fs::create_hard_link(d.at("o.json"), d.at("hard.json"));
  fs::create_symlink("o.json", d.at("link.json"));
  {
    OutputFiles files({d.at("scene.nff")});
    CHECK_THROWS_AS(files.add(d.at("scene.nff"), "--stats file"), UsageError);
    // The same scene through another spelling of its path.
    CHECK_THROWS_AS(files.add(d.at("./scene.nff"), "--stats file"), UsageError);
    files.add(d.at("o.json"), "--stats file");
    CHECK_THROWS_AS(files.add(d.at("hard.json"), "other"), UsageError);  // same inode
    CHECK_THROWS_AS(files.add(d.at("link.json"), "other"), UsageError);  // same target
    CHECK_THROWS_AS(files.add(d.at("sub/../o.json"), "other"), std::exception);
    // A new file named twice: by normalised path.
    files.add(d.at("new.json"), "a");
    CHECK_THROWS_AS(files.add(d.at("./new.json"), "b"), UsageError);
  }  // nothing committed: the temporaries go, the files stay
  CHECK(read(d.at("scene.nff")) == "precious scene");
  CHECK(read(d.at("o.json")) == "precious");
  CHECK(d.listing() == "hard.json link.json o.json scene.nff");
}

TEST_CASE("output files: a regular output appears whole at commit, keeps the old file's mode, and leaves no temporary") {
  ScratchDir d;
  write(d.at("o.json"), "old");
  ::chmod(d.at("o.json").c_str(), 0640);
  OutputFiles files;
  const std::size_t id = files.add(d.at("o.json"), "--stats file");
  // The temporary exists from add() on (that is how an unwritable place fails early).
  CHECK(d.listing().find(".raynode-") != std::string::npos);
  files.text(id, "new content");
  CHECK(read(d.at("o.json")) == "old");  // not before commit
  files.commit();
  CHECK(read(d.at("o.json")) == "new content");
  struct stat st {};
  REQUIRE(::stat(d.at("o.json").c_str(), &st) == 0);
  CHECK((st.st_mode & 0777) == 0640);
  CHECK(d.listing() == "o.json");
}

TEST_CASE("output files: update() puts each version in place whole, through a symlink") {
  ScratchDir d;
  write(d.at("real.csv"), "old");
  fs::create_symlink("real.csv", d.at("link.csv"));
  {
    OutputFiles files;
    const std::size_t id = files.add(d.at("link.csv"), "CSV");
    files.update(id, "a\n1\n");
    CHECK(read(d.at("real.csv")) == "a\n1\n");
    files.update(id, "a\n1\n2\n");
    CHECK(read(d.at("real.csv")) == "a\n1\n2\n");
    CHECK(fs::is_symlink(d.at("link.csv")));
  }  // destroyed without commit (an interrupted sweep): the last version stays
  CHECK(read(d.at("real.csv")) == "a\n1\n2\n");
  CHECK(d.listing() == "link.csv real.csv");
}

TEST_CASE("output files: unwritable places fail at add() with the user's path and the reason") {
  ScratchDir d;
  OutputFiles files;
  fs::create_directory(d.at("adir"));
  try {
    files.add(d.at("adir"), "image", false);
    FAIL("a directory in the way was accepted");
  } catch (const std::runtime_error& e) {
    CHECK(std::string(e.what()).find("a directory is in the way") != std::string::npos);
  }
  try {
    files.add(d.at("missing/o.png"), "image", false);
    FAIL("a missing directory was accepted");
  } catch (const std::runtime_error& e) {
    CHECK(std::string(e.what()).find("does not exist") != std::string::npos);
    CHECK(std::string(e.what()).find("missing/o.png") != std::string::npos);
  }
  try {
    files.add(d.at(std::string(300, 'a') + ".png"), "image", false);
    FAIL("a name longer than NAME_MAX was accepted");
  } catch (const std::runtime_error& e) {
    CHECK(std::string(e.what()).find("File name too long") != std::string::npos);
  }
  CHECK_THROWS_AS(files.add("-", "image", false), UsageError);  // a binary output needs a file
  files.add("-", "--stats file", true);
  CHECK(files.uses_stdout());
  CHECK_THROWS_AS(files.add("/dev/stdout", "--json file", true), UsageError);  // stdout twice
  CHECK(d.listing() == "adir");
}
