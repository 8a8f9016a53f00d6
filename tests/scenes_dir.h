// Where tests find ../shared/scenes: $RAYNODE_SCENES_DIR, else the path
// compiled in (the repository's sibling `shared/scenes`). Tests that need it
// call `scenes_dir()` and skip (with a message) when it returns empty.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <string>

namespace raynode::testing {

inline std::filesystem::path scenes_dir() {
  namespace fs = std::filesystem;
  if (const char* env = std::getenv("RAYNODE_SCENES_DIR"); env && *env) {
    if (fs::is_directory(env)) return env;
    return {};
  }
#ifdef RAYNODE_DEFAULT_SCENES_DIR
  if (fs::is_directory(RAYNODE_DEFAULT_SCENES_DIR)) return RAYNODE_DEFAULT_SCENES_DIR;
#endif
  return {};
}

}  // namespace raynode::testing

/// Skips the current doctest test case when ../shared/scenes is absent.
#define RAYNODE_REQUIRE_SCENES(dir)                                              \
  const std::filesystem::path dir = ::raynode::testing::scenes_dir();            \
  if (dir.empty()) {                                                             \
    MESSAGE("skipped: ../shared/scenes not found (set RAYNODE_SCENES_DIR)");     \
    return;                                                                      \
  }
