#include <doctest/doctest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "svm/paged_database.h"
#include "test_grid_params.h"
#include "test_scenes.h"

using namespace raynode;
using namespace raynode::svm;

namespace {

std::uint32_t word_at(const PagedImage& im, std::uint32_t page, std::uint32_t offset) {
  std::uint32_t w;
  std::memcpy(&w, im.page(page).data() + offset, 4);
  return w;
}

/// Cell c's directory entry, found at its key (the cell's index in the
/// linear order, its brick's page in the bricked one).
DirectoryEntry entry_of(const PagedImage& im, const core::GridInfo& g, std::uint32_t c) {
  const PageLayout& l = im.layout;
  const int x = int(c % std::uint32_t(g.res[0])), y = int(c / std::uint32_t(g.res[0]) % std::uint32_t(g.res[1])),
            z = int(c / std::uint32_t(g.res[0]) / std::uint32_t(g.res[1]));
  const std::uint32_t key = l.directory_key(g, x, y, z);
  REQUIRE(l.directory_offset(key) + 4 <= l.page_size);
  REQUIRE(l.directory_page(key) < l.directory_first + l.directory_pages);
  return word_at(im, l.directory_page(key), l.directory_offset(key));
}

/// Cell c as the image holds it: an empty cell's distance, or the ids it
/// lists (its directory entry's one id, or its list read from the lists
/// segment, checking that every word lies in a page of the segment); for a
/// packed cell, its run header's address and count.
struct CellRecord {
  bool empty = false, single = false, packed = false;
  std::uint32_t distance = 0, count = 0, header = 0;
  std::uint32_t first_page = 0, last_page = 0;  // of a list, header included
  std::vector<std::uint32_t> ids;
};

CellRecord record_of(const PagedImage& im, const core::GridInfo& g, std::uint32_t c) {
  const PageLayout& l = im.layout;
  const DirectoryEntry e = entry_of(im, g, c);
  CellRecord r;
  switch (e & kEntryTag) {  // the top two bits
    case kEmptyCell:
      r.empty = true;
      r.distance = e;  // the entry is the distance
      return r;
    case kSingleCell:
      r.single = true;
      r.ids.push_back(e & kMaxEntryValue);
      return r;
    case kPackedCell:
      r.packed = true;
      r.header = e & kMaxEntryValue;
      REQUIRE(l.block_address_page(r.header) >= l.block_first);
      REQUIRE(l.block_address_page(r.header) < l.block_first + l.block_pages);
      r.count = word_at(im, l.block_address_page(r.header), l.block_address_offset(r.header));
      return r;
    default: REQUIRE((e & kEntryTag) == kListCell); break;
  }
  const std::uint32_t list = e & kMaxEntryValue;
  auto word = [&](std::uint32_t a) {
    const std::uint32_t page = l.list_page(a);
    REQUIRE(page >= l.list_first);
    REQUIRE(page < l.list_first + l.list_pages);
    r.last_page = page;
    return word_at(im, page, l.list_offset(a));
  };
  r.first_page = l.list_page(list);
  r.count = word(list);
  for (std::uint32_t i = 0; i < r.count; ++i) r.ids.push_back(word(list + 4 + 4 * i));
  return r;
}

}  // namespace

TEST_CASE("paged database: every object is found in its page, byte for byte, for page sizes 64 B to 4 KiB, "
          "either directory order") {
  std::uint32_t seen_empty = 0, seen_single = 0, seen_listed = 0;
  for (auto [name, size] : {std::pair{"teapot", 2}, std::pair{"rings", 1}, std::pair{"balls", 1}})
  for (const DirectoryOrder order : {DirectoryOrder::kLinear, DirectoryOrder::kBricked}) {
    const testing::BuiltScene b = testing::build_spd(name, size);
    for (std::uint32_t ps : {64u, 128u, 1024u, 4096u}) {
      CAPTURE(name);
      CAPTURE(ps);
      CAPTURE(directory_order_name(order));
      const PagedImage im = build_paged_image(b.db, b.grid, ps, nullptr, order);
      const PageLayout& l = im.layout;
      CHECK(l.pages == l.directory_pages + l.list_pages + l.primitive_pages + l.normals_pages);
      CHECK(im.pages.size() == std::size_t(l.pages) * ps);
      // Cell lists equal the grid's, in the same order: an empty cell's
      // entry carries its empty-space distance, a one-primitive cell's its
      // id, the others' a header and the ids in the lists segment.
      std::uint32_t empty = 0, single = 0, listed = 0, ids = 0;
      for (std::uint32_t c = 0; c < b.grid.info.cell_count(); ++c) {
        const std::vector<std::uint32_t> expect(b.grid.cell_primitives.begin() + b.grid.cell_start[c],
                                                b.grid.cell_primitives.begin() + b.grid.cell_start[c + 1]);
        const CellRecord r = record_of(im, b.grid.info, c);
        REQUIRE(!r.packed);
        REQUIRE(r.ids == expect);
        REQUIRE(r.empty == expect.empty());
        REQUIRE(r.single == (expect.size() == 1));
        if (r.empty) REQUIRE(r.distance == b.grid.empty_distance[c]);
        empty += r.empty;
        single += r.single;
        if (expect.size() > 1) {
          ++listed;
          ids += std::uint32_t(expect.size());
        }
      }
      seen_empty += empty;
      seen_single += single;
      seen_listed += listed;
      CHECK(l.single_cells == single);
      CHECK(l.listed_cells == listed);
      CHECK(l.list_ids == ids);
      if (order == DirectoryOrder::kLinear) {
        CHECK(l.directory_pages == (b.grid.info.cell_count() * 4 + ps - 1) / ps);
      } else {  // a page per brick
        const core::CellBricks& k = l.bricks;
        CHECK(std::size_t(k.cells()) <= ps / 4);
        CHECK(l.directory_pages == std::uint32_t(k.bricks(b.grid.info, 0) * k.bricks(b.grid.info, 1) *
                                                 k.bricks(b.grid.info, 2)));
      }
      CHECK(l.object_bytes == b.db.primitives.size() * 64 + b.db.vertex_normals.size() * 36 +
                                  std::size_t(b.grid.info.cell_count()) * 4 + std::size_t(listed + ids) * 4);
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
  CHECK(seen_empty > 0);  // every kind of cell is exercised
  CHECK(seen_single > 0);
  CHECK(seen_listed > 0);
}

TEST_CASE("paged database: a list (header and ids) that fits in a page is never split, longer lists run on page after page") {
  const testing::BuiltScene b = testing::build_spd("teapot", 3);
  const PagedImage im = build_paged_image(b.db, b.grid, 64);  // 16 words per page
  std::size_t long_lists = 0;
  for (std::uint32_t c = 0; c < b.grid.info.cell_count(); ++c) {
    const CellRecord r = record_of(im, b.grid.info, c);
    if (r.empty || r.single) continue;
    const std::uint32_t words = 1 + r.count;  // the header and the ids
    if (words <= 16) CHECK(r.first_page == r.last_page);
    else {
      ++long_lists;
      CHECK(r.last_page - r.first_page + 1 <= (words + 15) / 16 + 1);
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
      std::size_t packed = 0, listed = 0, listed_cells = 0, spanning = 0;
      for (std::uint32_t c = 0; c < b.grid.info.cell_count(); ++c) {
        const std::uint32_t n = b.grid.cell_start[c + 1] - b.grid.cell_start[c];
        const std::uint32_t k0 = blocks.start[c], k1 = blocks.start[c + 1];
        const CellRecord r = record_of(im, b.grid.info, c);
        if (k0 == k1) {  // unpacked: the list as before
          REQUIRE(!r.packed);
          REQUIRE(r.ids.size() == n);
          if (n > 1) {
            listed += n;
            ++listed_cells;
          }
          continue;
        }
        ++packed;
        REQUIRE(r.packed);
        REQUIRE(r.count == n);
        REQUIRE(r.header % 32 == 0);  // the blocks stay 32-byte aligned
        // The header and the first block share a page; a run that fits in
        // a page stays in one; blocks never cross a page.
        const std::uint32_t first = l.block_address_page(l.packed_block_address(r.header, 0));
        const std::uint32_t last = l.block_address_page(l.packed_block_address(r.header, k1 - k0 - 1));
        REQUIRE(first == l.block_address_page(r.header));
        if (32 + (k1 - k0) * 320 <= ps) REQUIRE(first == last);
        else ++spanning;
        for (std::uint32_t k = k0; k < k1; ++k) {
          const std::uint32_t a = l.packed_block_address(r.header, k - k0);
          REQUIRE(a % 32 == 0);
          REQUIRE(l.block_address_page(a) < l.block_first + l.block_pages);
          REQUIRE(l.block_address_offset(a) + 320 <= ps);
          if (k > k0) REQUIRE(a > l.packed_block_address(r.header, k - k0 - 1));  // in order, none overlapping
          REQUIRE(std::memcmp(im.page(l.block_address_page(a)).data() + l.block_address_offset(a), &blocks.blocks[k],
                              320) == 0);
        }
      }
      CHECK(l.packed_cells == packed);
      CHECK(l.list_ids == listed);
      CHECK(l.listed_cells == listed_cells);
      CHECK(listed < b.grid.cell_primitives.size());  // packed cells keep no list
      CHECK(l.object_bytes == b.db.primitives.size() * 64 + b.db.vertex_normals.size() * 36 +
                                  std::size_t(b.grid.info.cell_count()) * 4 + (listed_cells + listed) * 4 + packed * 32 +
                                  blocks.blocks.size() * 320);
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

TEST_CASE("paged database: an adaptive grid pages the top directory, the sub-grids' cells and their records") {
  // A coarse top grid with sub-grids from 4 primitives: two levels below
  // the top even on small scenes.
  const core::GridParams gp = raynode::testing::small_scene_sub_grids(4, true);
  for (auto [name, size] : {std::pair{"teapot", 2}, std::pair{"tetra", 3}})
    for (const DirectoryOrder order : {DirectoryOrder::kLinear, DirectoryOrder::kBricked})
      for (std::uint32_t ps : {64u, 256u, 4096u}) {
        CAPTURE(name);
        CAPTURE(ps);
        CAPTURE(directory_order_name(order));
        testing::BuiltScene b = testing::build_spd(name, size);
        b.grid = core::build_grid(b.db, gp);
        const core::Grid& g = b.grid;
        REQUIRE(g.sub_grid_count() > 0);
        REQUIRE(g.depth() >= 2);
        const PagedImage im = build_paged_image(b.db, g, ps, nullptr, order);
        const PageLayout& l = im.layout;
        CHECK(l.cells == g.leaf_cells());
        CHECK(l.top_cells == g.info.cell_count());
        CHECK(l.sub_grids == g.sub_grids.size());
        CHECK(l.pages ==
              l.directory_pages + l.sub_grid_pages + l.list_pages + l.primitive_pages + l.normals_pages);
        CHECK(l.sub_grid_pages == (l.sub_grids * 64 + ps - 1) / ps);
        CHECK(l.directory_pages * (ps / 4) >= l.top_keys + (l.cells - l.top_cells));
        for (std::uint32_t p = l.sub_grid_first; p < l.sub_grid_first + l.sub_grid_pages; ++p)
          CHECK(l.segment(p) == Segment::kSubGrids);
        // Every entry of every grid: a sub-grid's code, or the cell's list.
        for (std::uint32_t e = 0; e < l.cells; ++e) {
          const std::uint32_t key = l.entry_key(g.info, e);
          REQUIRE(l.directory_page(key) < l.directory_first + l.directory_pages);
          const DirectoryEntry word = word_at(im, l.directory_page(key), l.directory_offset(key));
          if (g.cell_entries[e] & core::kSubGridEntry) {
            REQUIRE(word == core::kSubGridCode + (g.cell_entries[e] & ~core::kSubGridEntry));
            continue;
          }
          const std::uint32_t n = g.cell_start[e + 1] - g.cell_start[e];
          if (n == 0) REQUIRE(word == g.empty_distance[e]);
          else if (n == 1) REQUIRE(word == (kSingleCell | g.cell_primitives[g.cell_start[e]]));
          else REQUIRE((word & kEntryTag) == kListCell);
        }
        // Each record: the grid's description and its cell 0's key, which
        // is the key of the sub-grid's first entry.
        for (std::uint32_t i = 0; i < l.sub_grids; ++i) {
          PagedSubGrid r;
          const std::uint64_t a = l.sub_grid_address(i);
          REQUIRE((a & (ps - 1)) + 64 <= ps);
          std::memcpy(&r, im.pages.data() + a, sizeof r);
          CHECK(std::memcmp(&r.info, &g.sub_grids[i].info, sizeof r.info) == 0);
          CHECK((r.first_key & ~kLargeListKey) == l.entry_key(g.info, g.sub_grids[i].first_entry));
          CHECK(((r.first_key & kLargeListKey) != 0) == g.sub_grids[i].large_list);
        }
        CHECK(l.object_bytes == b.db.primitives.size() * 64 + b.db.vertex_normals.size() * 36 +
                                    std::size_t(l.cells) * 4 + std::size_t(l.sub_grids) * 64 +
                                    std::size_t(l.listed_cells + l.list_ids) * 4);
      }
}

TEST_CASE("paged database: in cell order the cells name their primitives by slot, first-listed first, and each "
          "slot holds its primitive's record") {
  std::uint32_t seen_normals = 0, seen_packed = 0;
  for (auto [name, size] : {std::pair{"teapot", 2}, std::pair{"rings", 1}, std::pair{"tetra", 3}})
    for (const DirectoryOrder order : {DirectoryOrder::kLinear, DirectoryOrder::kBricked})
      for (std::uint32_t ps : {64u, 1024u}) {
        CAPTURE(name);
        CAPTURE(ps);
        CAPTURE(directory_order_name(order));
        const testing::BuiltScene b = testing::build_spd(name, size);
        const core::CellBlocks blocks = core::build_cell_blocks(b.db, b.grid, 3);
        const bool pack = ps >= 1024 && !blocks.blocks.empty();
        const PagedImage im = build_paged_image(b.db, b.grid, ps, pack ? &blocks : nullptr, order, PrimitiveOrder::kCell);
        const PageLayout& l = im.layout;
        CHECK(l.primitive_order == PrimitiveOrder::kCell);
        const std::uint32_t n = std::uint32_t(b.db.primitives.size());
        const std::vector<std::uint32_t> slot = primitive_slots(l, b.grid, n);
        // A permutation of the ids.
        std::vector<bool> taken(n, false);
        for (std::uint32_t s : slot) {
          REQUIRE(s < n);
          REQUIRE(!taken[s]);
          taken[s] = true;
        }
        // Walked in key order, the cells meet the slots 0, 1, 2, ... the
        // first time they list a primitive; each cell names its list's
        // primitives by slot, in list order.
        std::vector<std::uint32_t> key_cell(l.top_keys, 0xffffffffu);
        for (std::uint32_t c = 0; c < l.top_cells; ++c) key_cell[l.entry_key(b.grid.info, c)] = c;
        std::uint32_t next = 0;
        std::vector<bool> met(n, false);
        for (std::uint32_t c : key_cell) {
          if (c == 0xffffffffu) continue;  // a bricked directory's padding
          std::vector<std::uint32_t> expect;
          for (std::uint32_t k = b.grid.cell_start[c]; k < b.grid.cell_start[c + 1]; ++k) {
            const std::uint32_t id = b.grid.cell_primitives[k];
            expect.push_back(slot[id]);
            if (!met[id]) {
              met[id] = true;
              REQUIRE(slot[id] == next++);
            }
          }
          const CellRecord r = record_of(im, b.grid.info, c);
          if (r.packed) {
            ++seen_packed;
            REQUIRE(r.count == expect.size());
            for (std::uint32_t i = 0; i < r.count; ++i) {
              core::TriangleBlock blk;
              const std::uint32_t a = l.packed_block_address(r.header, i / core::kBlockLanes);
              std::memcpy(&blk, im.page(l.block_address_page(a)).data() + l.block_address_offset(a), sizeof blk);
              REQUIRE(blk.primitive[i % core::kBlockLanes] == expect[i]);
            }
          } else {
            REQUIRE(r.ids == expect);
          }
        }
        // Each slot holds its primitive's record; vertex normals follow
        // their triangles, the record naming the set's new place.
        for (std::uint32_t id = 0; id < n; ++id) {
          core::Primitive p;
          std::memcpy(&p, im.page(l.primitive_page(slot[id])).data() + l.primitive_offset(slot[id]), sizeof p);
          const core::Primitive& want = b.db.primitives[id];
          REQUIRE(p.kind == want.kind);
          REQUIRE(p.material == want.material);
          REQUIRE(p.shape == want.shape);
          REQUIRE(std::memcmp(p.data, want.data, sizeof p.data) == 0);
          REQUIRE((p.normals == core::kNoNormals) == (want.normals == core::kNoNormals));
          if (p.normals == core::kNoNormals) continue;
          ++seen_normals;
          REQUIRE(p.normals < l.normal_sets);
          REQUIRE(std::memcmp(im.page(l.normals_page(p.normals)).data() + l.normals_offset(p.normals),
                              &b.db.vertex_normals[want.normals], sizeof(core::TriangleNormals)) == 0);
        }
      }
  CHECK(seen_normals > 0);  // teapot's patches
  CHECK(seen_packed > 0);
}
