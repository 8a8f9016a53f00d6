// libFuzzer target for the NFF reader (core/nff.h): any bytes either parse
// into a scene or throw core::ParseError located inside the text; nothing
// else may escape, crash, hang or trip a sanitizer. A scene the reader
// accepts must survive the writer unchanged (write, read, write gives the
// same text), and, when small, must build a database and a grid and render
// a 3x3 image.
//
// Place in the data flow: bytes -> parse_nff -> Scene -> write_nff ->
// parse_nff -> make_database -> build_grid (+ build_cell_blocks) -> render. Crashes found here become cases
// in tests/core/nff_regression_test.cpp.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <stdexcept>
#include <sstream>
#include <string>
#include <string_view>

#include "core/cell_blocks.h"
#include "core/database.h"
#include "core/direct_view.h"
#include "core/grid.h"
#include "core/nff.h"
#include "core/render.h"

namespace {

[[noreturn]] void fail(const std::string& what) {
  std::fprintf(stderr, "nff_fuzzer: %s\n", what.c_str());
  std::abort();
}

std::string to_nff(const raynode::core::Scene& s) {
  std::ostringstream out;
  raynode::core::write_nff(out, s);
  return out.str();
}

/// Lines in `text`, counting a final line without a newline.
int line_count(std::string_view text) {
  int n = 1;
  for (char c : text) n += c == '\n';
  return n;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace raynode::core;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  Scene scene;
  try {
    scene = parse_nff(text, "fuzz.nff");
  } catch (const ParseError& e) {
    if (e.line() < 1 || e.line() > line_count(text) || e.column() < 1 || e.message().empty())
      fail(std::string("badly located error: ") + e.what());
    return 0;
  } catch (const std::exception& e) {
    fail(std::string("unexpected exception from parse_nff: ") + e.what());
  }
  // Accepted: the writer must reproduce it.
  std::string once, twice;
  try {
    once = to_nff(scene);
    twice = to_nff(parse_nff(once, "rewritten.nff"));
  } catch (const std::exception& e) {
    fail(std::string("the rewritten scene does not parse: ") + e.what());
  }
  if (once != twice) fail("round trip changed the scene:\n" + once + "\n---\n" + twice);
  // Small scenes go on through the database and the grid.
  if (scene.shapes.size() <= 64 && scene.vertices.size() <= 1024) {
    try {
      const Database db = make_database(scene);
      const Grid grid = build_grid(db);
      for (int a = 0; a < 3; ++a)
        if (grid.info.res[a] < 1) fail("grid with a zero resolution");
      // A few rays through the grid (3D-DDA, every primitive test, shading).
      RenderParams rp;
      rp.width = rp.height = 3;
      rp.max_depth = 3;
      try {
        render(db, grid, rp);
        // Again with every non-empty cell packed into triangle blocks (the
        // CLI's default path packs cells of 3 or more).
        const CellBlocks blocks = build_cell_blocks(db, grid, 1, PackKinds::kTrianglesAndSpheres);
        render_image(DirectView(db, grid, &blocks), db, rp);
      } catch (const std::runtime_error& e) {
        // The one refusal allowed: no view, and bounds too large for a default camera.
        if (std::string_view(e.what()).find("reaches too far for a default camera") == std::string_view::npos) throw;
      }
    } catch (const std::exception& e) {
      fail(std::string("database, grid or render of an accepted scene failed: ") + e.what());
    }
  }
  return 0;
}
