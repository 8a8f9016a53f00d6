#include <doctest/doctest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstring>
#include <stdexcept>

#include "svm/paged_database.h"
#include "test_scenes.h"

using namespace raynode;
using namespace raynode::svm;

namespace {

/// Reads cell c's list out of the image, checking that every piece lies in
/// one page of the lists segment.
std::vector<std::uint32_t> list_of(const PagedImage& im, std::uint32_t c) {
  const PageLayout& l = im.layout;
  DirectoryEntry e;
  std::memcpy(&e, im.page(l.directory_page(c)).data() + l.directory_offset(c), sizeof e);
  std::vector<std::uint32_t> ids;
  std::uint32_t a = e.list;
  for (std::uint32_t i = 0; i < e.count; ++i, a += 4) {
    const std::uint32_t page = l.list_page(a);
    REQUIRE(page >= l.list_first);
    REQUIRE(page < l.list_first + l.list_pages);
    std::uint32_t id;
    std::memcpy(&id, im.page(page).data() + l.list_offset(a), 4);
    ids.push_back(id);
  }
  return ids;
}

}  // namespace

TEST_CASE("paged database: every object is found in its page, byte for byte, for page sizes 64 B to 4 KiB") {
  for (auto [name, size] : {std::pair{"teapot", 2}, std::pair{"rings", 1}, std::pair{"balls", 1}}) {
    const testing::BuiltScene b = testing::build_spd(name, size);
    for (std::uint32_t ps : {64u, 128u, 1024u, 4096u}) {
      CAPTURE(name);
      CAPTURE(ps);
      const PagedImage im = build_paged_image(b.db, b.grid, ps);
      const PageLayout& l = im.layout;
      CHECK(l.pages == l.directory_pages + l.list_pages + l.primitive_pages + l.normals_pages);
      CHECK(im.pages.size() == std::size_t(l.pages) * ps);
      CHECK(l.object_bytes == b.db.primitives.size() * 64 + b.db.vertex_normals.size() * 36 +
                                  std::size_t(b.grid.info.cell_count()) * 8 + b.grid.cell_primitives.size() * 4);
      // Cell lists equal the grid's, in the same order.
      for (std::uint32_t c = 0; c < b.grid.info.cell_count(); ++c) {
        const std::vector<std::uint32_t> expect(b.grid.cell_primitives.begin() + b.grid.cell_start[c],
                                                b.grid.cell_primitives.begin() + b.grid.cell_start[c + 1]);
        REQUIRE(list_of(im, c) == expect);
        if (expect.empty()) {  // the entry carries the cell's empty-space distance instead
          DirectoryEntry e;
          std::memcpy(&e, im.page(l.directory_page(c)).data() + l.directory_offset(c), sizeof e);
          REQUIRE(e.count == 0);
          REQUIRE(e.list == b.grid.empty_distance[c]);
        }
      }
      // Records equal the database's; none crosses a page boundary.
      for (std::uint32_t id = 0; id < b.db.primitives.size(); ++id) {
        REQUIRE(l.primitive_offset(id) + 64 <= ps);
        REQUIRE(std::memcmp(im.page(l.primitive_page(id)).data() + l.primitive_offset(id), &b.db.primitives[id], 64) ==
                0);
      }
      for (std::uint32_t id = 0; id < b.db.vertex_normals.size(); ++id) {
        REQUIRE(l.normals_offset(id) + 36 <= ps);
        REQUIRE(std::memcmp(im.page(l.normals_page(id)).data() + l.normals_offset(id), &b.db.vertex_normals[id], 36) ==
                0);
      }
    }
  }
}

TEST_CASE("paged database: a list that fits in a page is never split; longer lists run on page after page") {
  const testing::BuiltScene b = testing::build_spd("teapot", 3);
  const PagedImage im = build_paged_image(b.db, b.grid, 64);  // 16 ids per page
  const PageLayout& l = im.layout;
  std::size_t long_lists = 0;
  for (std::uint32_t c = 0; c < b.grid.info.cell_count(); ++c) {
    DirectoryEntry e;
    std::memcpy(&e, im.page(l.directory_page(c)).data() + l.directory_offset(c), sizeof e);
    if (e.count == 0) continue;
    const std::uint32_t first = l.list_page(e.list), last = l.list_page(e.list + 4 * (e.count - 1));
    if (e.count <= 16) CHECK(first == last);
    else {
      ++long_lists;
      CHECK(last - first + 1 <= (e.count + 15) / 16 + 1);
    }
  }
  CHECK(long_lists > 0);  // the case is exercised
}

TEST_CASE("paged database: page sizes that are not a power of two or below one primitive are refused") {
  const testing::BuiltScene b = testing::build_spd("rings", 1);
  CHECK_THROWS_AS(build_paged_image(b.db, b.grid, 1000), std::invalid_argument);
  CHECK_THROWS_AS(build_paged_image(b.db, b.grid, 32), std::invalid_argument);
  CHECK_THROWS_WITH_AS(build_paged_image(b.db, b.grid, 0), doctest::Contains("power of two"), std::invalid_argument);
  CHECK_NOTHROW(build_paged_image(b.db, b.grid, 64));
}

TEST_CASE("paged database: packed cells (--pack-cells) hold their blocks in the blocks segment, none across a page") {
  const testing::BuiltScene b = testing::build_spd("teapot", 3);
  for (std::uint32_t pack : {1u, 3u})
    for (std::uint32_t ps : {512u, 1024u, 4096u}) {
      CAPTURE(pack);
      CAPTURE(ps);
      const core::CellBlocks blocks = core::build_cell_blocks(b.db, b.grid, pack);
      REQUIRE(!blocks.blocks.empty());
      const PagedImage im = build_paged_image(b.db, b.grid, ps, &blocks);
      const PageLayout& l = im.layout;
      const std::uint32_t per_page = ps / 320;
      CHECK(l.blocks_per_page == per_page);
      CHECK(l.pack_min == pack);
      CHECK(l.blocks == blocks.blocks.size());
      CHECK(l.pages == l.directory_pages + l.list_pages + l.primitive_pages + l.normals_pages + l.block_pages);
      // Every page's segment (the faults' breakdown) is the one whose range holds it.
      std::uint32_t in_segment[kSegments] = {};
      for (std::uint32_t p = 0; p < l.pages; ++p) ++in_segment[std::size_t(l.segment(p))];
      CHECK(in_segment[std::size_t(Segment::kDirectory)] == l.directory_pages);
      CHECK(in_segment[std::size_t(Segment::kLists)] == l.list_pages);
      CHECK(in_segment[std::size_t(Segment::kPrimitives)] == l.primitive_pages);
      CHECK(in_segment[std::size_t(Segment::kNormals)] == l.normals_pages);
      CHECK(in_segment[std::size_t(Segment::kBlocks)] == l.block_pages);
      CHECK(l.segment(l.block_first) == Segment::kBlocks);
      CHECK(l.segment(l.block_first - 1) != Segment::kBlocks);
      std::size_t packed = 0, listed = 0, spanning = 0;
      for (std::uint32_t c = 0; c < b.grid.info.cell_count(); ++c) {
        const std::uint32_t n = b.grid.cell_start[c + 1] - b.grid.cell_start[c];
        const std::uint32_t k0 = blocks.start[c], k1 = blocks.start[c + 1];
        DirectoryEntry e;
        std::memcpy(&e, im.page(l.directory_page(c)).data() + l.directory_offset(c), sizeof e);
        if (k0 == k1) {  // unpacked: the list as before
          REQUIRE((e.count & kPackedCell) == 0);
          REQUIRE(e.count == n);
          if (n > 0) REQUIRE(list_of(im, c).size() == n);
          listed += n;
          continue;
        }
        ++packed;
        REQUIRE(e.count == (n | kPackedCell));
        const std::uint32_t slot0 = l.block_slot(e.list);
        REQUIRE(l.block_address(slot0) == e.list);
        REQUIRE(l.block_address_page(e.list) == l.block_page(slot0));
        REQUIRE(l.block_address_offset(e.list) == l.block_offset(slot0));
        const std::uint32_t first = l.block_page(slot0), last = l.block_page(slot0 + (k1 - k0) - 1);
        if (k1 - k0 <= per_page) REQUIRE(first == last);  // a cell that fits in a page stays in one
        else ++spanning;
        for (std::uint32_t k = k0, slot = slot0; k < k1; ++k, ++slot) {
          REQUIRE(l.block_page(slot) >= l.block_first);
          REQUIRE(l.block_page(slot) < l.block_first + l.block_pages);
          REQUIRE(l.block_offset(slot) + 320 <= ps);
          REQUIRE(std::memcmp(im.page(l.block_page(slot)).data() + l.block_offset(slot), &blocks.blocks[k], 320) == 0);
        }
      }
      CHECK(l.packed_cells == packed);
      CHECK(l.list_ids == listed);
      CHECK(listed < b.grid.cell_primitives.size());  // packed cells keep no list
      CHECK(l.object_bytes == b.db.primitives.size() * 64 + b.db.vertex_normals.size() * 36 +
                                  std::size_t(b.grid.info.cell_count()) * 8 + listed * 4 + blocks.blocks.size() * 320);
      if (ps == 512) CHECK(spanning > 0);  // the chained case is exercised
    }
  // A page smaller than a block cannot hold one.
  const core::CellBlocks blocks = core::build_cell_blocks(b.db, b.grid, 3);
  CHECK_THROWS_WITH_AS(build_paged_image(b.db, b.grid, 256, &blocks), doctest::Contains("320-byte block"),
                       std::invalid_argument);
}

TEST_CASE("paged database: a grid without its empty-space distances is refused, not read past its end") {
  testing::BuiltScene b = testing::build_spd("rings", 1);
  b.grid.empty_distance.clear();
  CHECK_THROWS_WITH_AS(build_paged_image(b.db, b.grid, 1024), doctest::Contains("empty-space distances"),
                       std::invalid_argument);
}

TEST_CASE("paged database: pages are dealt round robin, every page has exactly one home") {
  PageLayout l;
  l.pages = 103;
  for (std::uint32_t n : {1u, 2u, 7u, 64u, 200u}) {
    std::uint32_t sum = 0;
    for (std::uint32_t i = 0; i < n; ++i) {
      sum += l.home_pages(i, n);
      CHECK(l.home_pages(i, n) <= (l.pages + n - 1) / n);
    }
    CHECK(sum == l.pages);
    for (std::uint32_t p = 0; p < l.pages; ++p) CHECK(PageLayout::home_slot(p, n) < l.home_pages(PageLayout::home(p, n), n));
  }
}

TEST_CASE("paged database: a protected host image cannot be read (the reader dies of SIGSEGV)") {
  HostPages pages(4096);
  pages.data()[10] = std::byte{42};
  pages.protect();
  CHECK(pages.is_protected());
  const pid_t pid = fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    std::signal(SIGSEGV, SIG_DFL);  // die of it (doctest would catch it)
    volatile const std::byte* p = pages.data() + 10;
    const int v = int(*p);
    _exit(v == 42 ? 0 : 1);  // reached only if the read did not fault
  }
  int status = 0;
  REQUIRE(waitpid(pid, &status, 0) == pid);
  CHECK(WIFSIGNALED(status));
  if (WIFSIGNALED(status)) CHECK(WTERMSIG(status) == SIGSEGV);
  pages.unprotect();
  CHECK(pages.data()[10] == std::byte{42});
}
