#include <doctest/doctest.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <memory_resource>
#include <string>
#include <vector>

#include "nodes/arena.h"

using namespace raynode::nodes;

TEST_CASE("arena: the budget is exact to the byte and refusals name the sizes") {
  Arena arena(3, 1000);
  void* a = arena.allocate_bytes(600, 8, "the first part");
  void* b = arena.allocate_bytes(400, 8, "the second part");  // exactly the budget
  CHECK(arena.used() == 1000);
  CHECK(arena.available() == 0);
  try {
    arena.allocate_bytes(1, 1, "one more byte");
    FAIL("an over-budget allocation must throw");
  } catch (const ArenaExhausted& e) {
    CHECK(e.node == 3);
    CHECK(e.requested == 1);
    CHECK(e.in_use == 1000);
    CHECK(e.budget == 1000);
    const std::string what = e.what();
    CHECK(what.find("node 3") != std::string::npos);
    CHECK(what.find("one more byte") != std::string::npos);
    CHECK(what.find("1000") != std::string::npos);
  }
  CHECK(arena.used() == 1000);  // a refusal changes nothing
  arena.deallocate_bytes(a, 600, 8);
  CHECK(arena.used() == 400);
  CHECK(arena.peak() == 1000);
  void* c = arena.allocate_bytes(600, 8, "again");
  CHECK(arena.used() == 1000);
  arena.deallocate_bytes(b, 400, 8);
  arena.deallocate_bytes(c, 600, 8);
  CHECK(arena.used() == 0);
}

TEST_CASE("arena: std::pmr containers allocate from it and are refused past the budget") {
  Arena arena(0, 4096);
  std::pmr::vector<int> v(&arena);
  v.reserve(512);  // 2048 B
  CHECK(arena.used() == 2048);
  CHECK_THROWS_AS(v.reserve(2048), ArenaExhausted);  // 8192 B > 4096
  CHECK(v.capacity() == 512);
  v.shrink_to_fit();
  v = std::pmr::vector<int>(&arena);
  CHECK(arena.used() == 0);
}

TEST_CASE("arena: ArenaArray value-initialises, frees on destruction and refuses huge counts without overflow") {
  Arena arena(5, 1 << 20);
  {
    ArenaArray<double> a(arena, 1000, "doubles");
    CHECK(arena.used() == 8000);
    for (std::size_t i = 0; i < a.size(); ++i) CHECK(a[i] == 0.0);
    ArenaArray<double> b = std::move(a);
    CHECK(arena.used() == 8000);
    CHECK(b.size() == 1000);
  }
  CHECK(arena.used() == 0);
  CHECK_THROWS_AS(ArenaArray<double>(arena, std::size_t(1) << 62, "too many"), ArenaExhausted);
  CHECK(arena.used() == 0);
}

namespace {
/// This process's resident set in bytes (/proc/self/statm), or 0 if unknown.
std::size_t resident_bytes() {
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  if (!f) return 0;
  unsigned long long size = 0, resident = 0;
  const int got = std::fscanf(f, "%llu %llu", &size, &resident);
  std::fclose(f);
  return got == 2 ? std::size_t(resident) * std::size_t(sysconf(_SC_PAGESIZE)) : 0;
}
}  // namespace

TEST_CASE("arena: an uninitialised ArenaArray is charged and refused like any other, and touches no memory") {
  constexpr std::size_t kBytes = std::size_t(64) << 20;
  Arena arena(2, kBytes);
  struct alignas(64) Line {
    std::byte bytes[64];
  };
  const std::size_t before = resident_bytes();
  REQUIRE(before > 0);
  {
    ArenaArray<Line> frames(arena, kBytes / sizeof(Line), "its frames", kUninitialized);
    CHECK(arena.used() == kBytes);
    CHECK(frames.size() == kBytes / sizeof(Line));
    // Nothing was written: the operating system backs none of it yet (a
    // page cache that the render never fills costs no host memory).
    CHECK(resident_bytes() < before + kBytes / 4);
    frames[frames.size() - 1].bytes[63] = std::byte{7};
    CHECK(frames[frames.size() - 1].bytes[63] == std::byte{7});
    CHECK_THROWS_AS(ArenaArray<Line>(arena, 1, "one more line", kUninitialized), ArenaExhausted);
  }
  CHECK(arena.used() == 0);
  {
    // The contrast, so that the check above can fail: value-initialised
    // arrays are written, page by page.
    const std::size_t zeroed_before = resident_bytes();
    ArenaArray<Line> zeroed(arena, kBytes / sizeof(Line), "its zeroed frames");
    CHECK(resident_bytes() >= zeroed_before + kBytes / 2);
  }
  // copy_to_arena copies into uninitialised memory: every byte is the source's.
  std::vector<std::uint32_t> src(10000);
  for (std::size_t i = 0; i < src.size(); ++i) src[i] = std::uint32_t(i * 2654435761u);
  const ArenaArray<std::uint32_t> copy = copy_to_arena(arena, std::span<const std::uint32_t>(src), "a copy");
  CHECK(arena.used() == src.size() * sizeof(std::uint32_t));
  CHECK(std::vector<std::uint32_t>(copy.span().begin(), copy.span().end()) == src);
}

TEST_CASE("arena: format_bytes reads like the budget flags") {
  CHECK(format_bytes(4u << 20) == "4 MiB");
  CHECK(format_bytes(1536) == "1.5 KiB");
  CHECK(format_bytes(733) == "733 B");
}
