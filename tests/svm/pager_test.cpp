#include <doctest/doctest.h>

#include <cstring>
#include <stdexcept>
#include <utility>
#include <vector>

#include "nodes/machine.h"
#include "svm/paged_view.h"
#include "svm/pager.h"
#include "test_scenes.h"

using namespace raynode;
using namespace raynode::svm;

namespace {

/// Runs `client` on node 0 with a pager of `cache` frames over `image`
/// dealt to 2 nodes; node 1 serves page requests until node 0 is done.
void with_two_nodes(const PagedImage& image, std::uint32_t cache,
                    const std::function<void(Pager&, nodes::NodeContext&)>& client,
                    const nodes::NetworkModel& network = {}) {
  nodes::MachineParams mp;
  mp.nodes = 2;
  mp.node_memory = 4 * nodes::kMiB;
  mp.max_payload = sizeof(PageReplyMsg) + image.layout.page_size;
  mp.timeout_s = 60;
  mp.network = network;
  nodes::Machine machine(mp);
  machine.run(
      [&](nodes::NodeContext& ctx) {
        Pager pager(ctx, image.layout, ctx.id() == 0 ? cache : 0);
        for (std::uint32_t p = ctx.id(); p < image.layout.pages; p += 2)
          std::memcpy(pager.home_frame(p), image.page(p).data(), image.layout.page_size);
        if (ctx.id() == 0) {
          client(pager, ctx);
          ctx.send(1, nodes::MessageType::kTest, std::uint32_t(0));
        } else {
          while (true) {
            const nodes::Message m = ctx.receive(nodes::WaitKind::kIdle);
            if (m.type() == nodes::MessageType::kTest) break;
            REQUIRE(pager.serve(m));
          }
        }
      },
      [](nodes::NodeContext&) {});
}

}  // namespace

TEST_CASE("pager: at(address) reads the byte at any offset of a home, fetched or refetched page") {
  const testing::BuiltScene b = testing::build_spd("teapot", 2);
  for (std::uint32_t page_size : {64u, 256u, 1024u}) {
    CAPTURE(page_size);
    const PagedImage image = build_paged_image(b.db, b.grid, page_size);
    const PageLayout& l = image.layout;
    REQUIRE(l.pages > 6);
    with_two_nodes(image, 1, [&](Pager& pager, nodes::NodeContext&) {
      // Offsets 0, a middle one and the last byte, on pages homed at node 0
      // (even) and node 1 (odd: fetched into the one cache frame, which
      // each odd page evicts from the next).
      std::uint32_t checked = 0;
      for (std::uint32_t p : {0u, 1u, 2u, 3u, 1u, l.pages - 1, l.pages - 2, 5u})
        for (std::uint32_t at : {0u, page_size / 2 + 8, page_size - 1}) {
          pager.begin_pixel();
          const std::byte got = *pager.at(l.address(p) + at);
          REQUIRE(got == image.page(p)[at]);
          ++checked;
        }
      CHECK(checked == 24);
      CHECK(pager.stats().misses > 4);
      CHECK(pager.stats().evictions > 3);
      CHECK(pager.stats().accesses == 24);
    });
  }
}

TEST_CASE("pager: every access to a cached page counts as a cache page access, home pages' accesses do not") {
  const testing::BuiltScene b = testing::build_spd("teapot", 2);
  const PagedImage image = build_paged_image(b.db, b.grid, 256);
  const PageLayout& l = image.layout;
  REQUIRE(l.pages > 8);
  for (std::uint32_t cache : {1u, 2u, 64u}) {  // evicting, and with free frames (no LRU order kept)
    CAPTURE(cache);
    with_two_nodes(image, cache, [&](Pager& pager, nodes::NodeContext&) {
      // Node 0 is home of the even pages; the odd ones are cached.
      std::uint64_t odd = 0, all = 0;
      for (int pixel = 0; pixel < 3; ++pixel) {
        pager.begin_pixel();
        for (std::uint32_t p : {0u, 1u, 1u, 2u, 3u, 3u, 3u, 4u, 1u, 7u, 6u})
          for (std::uint32_t at : {0u, 100u}) {
            REQUIRE(*pager.at(l.address(p) + at) == image.page(p)[at]);
            odd += p % 2;
            ++all;
          }
      }
      pager.end_pixel();
      CHECK(pager.stats().accesses == all);
      CHECK(pager.stats().cache_page_accesses == odd);
      CHECK(pager.stats().misses > 0);
    });
  }
}

TEST_CASE("pager: a miss fetches the page's bytes from its home node, LRU evicts the least recently used page") {
  const testing::BuiltScene b = testing::build_spd("teapot", 2);
  const PagedImage image = build_paged_image(b.db, b.grid, 64);
  REQUIRE(image.layout.pages > 8);
  with_two_nodes(image, 2, [&](Pager& pager, nodes::NodeContext&) {
    // One pixel per access: recency is updated at a page's first access in a pixel.
    auto same = [&](std::uint32_t p) {
      pager.begin_pixel();
      return std::memcmp(pager.access(p), image.page(p).data(), 64) == 0;
    };
    const std::uint32_t A = 1, B = 3, C = 5;  // homed at node 1
    CHECK(same(0));                            // home: no fault
    CHECK(pager.stats().misses == 0);
    CHECK(same(A));
    CHECK(same(B));
    CHECK(same(A));  // hit; A is now more recent than B
    CHECK(pager.stats().misses == 2);
    CHECK(same(C));  // cache full: evicts B, the LRU page
    CHECK(pager.resident(A));
    CHECK(!pager.resident(B));
    CHECK(pager.resident(C));
    CHECK(same(B));  // evicts A
    CHECK(!pager.resident(A));
    CHECK(pager.resident(C));
    CHECK(pager.stats().misses == 4);
    CHECK(pager.stats().evictions == 2);
    CHECK(pager.stats().accesses == 6);
    // Counted from B's fault, which filled the cache: A's touch, C and B.
    CHECK(pager.stats().cache_accesses == 3);
    CHECK(pager.stats().cache_misses == 2);
    CHECK(pager.stats().lru_updates() == 2 + 3);  // the order built of A and B, then one per cache access
    CHECK(pager.resident(0));
  });
}

TEST_CASE("pager: recency is a page's first access in each pixel, not its later accesses in the pixel") {
  const testing::BuiltScene b = testing::build_spd("teapot", 2);
  const PagedImage image = build_paged_image(b.db, b.grid, 64);
  with_two_nodes(image, 2, [&](Pager& pager, nodes::NodeContext&) {
    const std::uint32_t A = 1, B = 3, C = 5;
    pager.begin_pixel();
    pager.access(A);
    pager.access(B);
    pager.access(A);  // same pixel: A stays older than B
    CHECK(pager.stats().cache_accesses == 0);  // B filled the cache: the order was built of A, then B
    CHECK(pager.stats().lru_updates() == 2);
    pager.begin_pixel();
    pager.access(A);  // a new pixel: A becomes the most recent
    pager.access(C);  // evicts B, not A
    CHECK(pager.resident(A));
    CHECK(!pager.resident(B));
    CHECK(pager.resident(C));
    pager.access(B);  // same pixel: A and C were first touched in it, A first: A goes
    CHECK(!pager.resident(A));
    CHECK(pager.resident(C));
    CHECK(pager.stats().accesses == 6);
    CHECK(pager.stats().misses == 4);
    CHECK(pager.pixel_pages() == 3);
    pager.end_pixel();
    CHECK(pager.stats().pixels == 2);
    CHECK(pager.stats().pixel_pages == 2 + 3);
  });
}

TEST_CASE("pager: pages per pixel counts distinct pages, home and remote, and restarts at each pixel") {
  const testing::BuiltScene b = testing::build_spd("teapot", 2);
  const PagedImage image = build_paged_image(b.db, b.grid, 64);
  with_two_nodes(image, 4, [&](Pager& pager, nodes::NodeContext&) {
    pager.begin_pixel();
    for (std::uint32_t p : {0u, 0u, 2u, 1u, 1u, 3u, 0u}) pager.access(p);
    CHECK(pager.pixel_pages() == 4);
    pager.begin_pixel();
    pager.access(2);
    pager.access(2);
    CHECK(pager.pixel_pages() == 1);
    pager.end_pixel();
    CHECK(pager.stats().pixels == 2);
    CHECK(pager.stats().pixel_pages == 5);
    CHECK(pager.stats().pixel_pages_max == 4);
    CHECK(pager.stats().pages_per_pixel() == doctest::Approx(2.5));
  });
}

TEST_CASE("pager: a fault waits for the reply in virtual time: 2 latencies + service, booked as communication") {
  const testing::BuiltScene b = testing::build_spd("teapot", 2);
  const PagedImage image = build_paged_image(b.db, b.grid, 64);
  nodes::NetworkModel net;
  net.latency_s = 1.0;
  net.service_s = 0.5;
  with_two_nodes(
      image, 1,
      [&](Pager& pager, nodes::NodeContext& ctx) {
        const double t0 = ctx.now();
        pager.access(1);
        const double t1 = ctx.now();
        CHECK(t1 - t0 >= 2.49);
        CHECK(t1 - t0 < 2.6);
        CHECK(ctx.counters().communication_s >= 2.49);
        pager.access(1);  // resident: no wait
        CHECK(ctx.now() - t1 < 0.05);
      },
      net);
}

TEST_CASE("pager: a request for a page that does not live on the node is a protocol error") {
  const testing::BuiltScene b = testing::build_spd("teapot", 2);
  const PagedImage image = build_paged_image(b.db, b.grid, 64);
  nodes::MachineParams mp;
  mp.nodes = 2;
  mp.max_payload = 128;
  mp.timeout_s = 60;
  nodes::Machine machine(mp);
  CHECK_THROWS_WITH_AS(machine.run(
                           [&](nodes::NodeContext& ctx) {
                             Pager pager(ctx, image.layout, 1);
                             if (ctx.id() == 0) {
                               ctx.send(1, nodes::MessageType::kPageRequest, PageRequestMsg{2});  // homed at node 0
                               ctx.receive(nodes::WaitKind::kIdle);
                             } else {
                               pager.serve(ctx.receive(nodes::WaitKind::kIdle));
                             }
                           },
                           [](nodes::NodeContext&) {}),
                       doctest::Contains("does not live here"), nodes::NodeError);
}

TEST_CASE("pager: LRU stays exact when a pixel first-touches more pages than the touched list holds") {
  // The touched list (kPagerTouchedCapacity first touches) is flushed when
  // full, in the middle of a pixel: the order of the pages' LRU stamps must
  // still be their first-touch order.
  const testing::BuiltScene b = testing::build_spd("teapot", 8);
  const PagedImage image = build_paged_image(b.db, b.grid, 64);
  const std::uint32_t cache = kPagerTouchedCapacity + 44;
  REQUIRE(image.layout.pages > 2 * (cache + 2));
  auto remote = [](std::uint32_t k) { return 2 * k + 1; };  // pages homed at node 1
  with_two_nodes(image, cache, [&](Pager& pager, nodes::NodeContext&) {
    pager.begin_pixel();
    for (std::uint32_t k = 0; k < cache; ++k) pager.access(remote(k));  // fills the cache
    CHECK(pager.stats().misses == cache);
    pager.begin_pixel();
    // Touch all but page k = 7, past the list's capacity, then fault twice.
    for (std::uint32_t k = 0; k < cache; ++k)
      if (k != 7) pager.access(remote(k));
    CHECK(pager.stats().misses == cache);
    pager.access(remote(cache));  // evicts k = 7, the only page this pixel left alone
    CHECK(!pager.resident(remote(7)));
    pager.access(remote(cache + 1));  // then k = 0, the pixel's first touch
    CHECK(!pager.resident(remote(0)));
    for (std::uint32_t k = 1; k < cache + 2; ++k)
      if (k != 7) CHECK(pager.resident(remote(k)));
    pager.end_pixel();
    CHECK(pager.stats().evictions == 2);
    CHECK(pager.stats().pixel_pages == cache + (cache - 1 + 2));
    // Each page once per pixel it was touched in: in the first pixel as the
    // order was built (the cache filled), in the second as cache accesses.
    CHECK(pager.stats().lru_order_frames == cache);
    CHECK(pager.stats().cache_accesses == cache - 1 + 2);
    CHECK(pager.stats().lru_updates() == cache + (cache - 1 + 2));
  });
}

TEST_CASE("pager: a page fetched again within its pixel (1-page cache) counts one more cache access") {
  const testing::BuiltScene b = testing::build_spd("teapot", 2);
  const PagedImage image = build_paged_image(b.db, b.grid, 64);
  with_two_nodes(image, 1, [&](Pager& pager, nodes::NodeContext&) {
    const std::uint32_t A = 1, B = 3;
    pager.begin_pixel();
    CHECK(std::memcmp(pager.access(A), image.page(A).data(), 64) == 0);
    CHECK(std::memcmp(pager.access(B), image.page(B).data(), 64) == 0);  // evicts A
    CHECK(std::memcmp(pager.access(A), image.page(A).data(), 64) == 0);  // fetched again
    pager.access(0);                                                     // home
    pager.end_pixel();
    CHECK(pager.stats().misses == 3);
    // A's first fault filled the cache; from there B and A's second fetch.
    CHECK(pager.stats().cache_accesses == 2);
    CHECK(pager.stats().cache_miss_ratio() == doctest::Approx(1.0));
    CHECK(pager.stats().lru_updates() == 3);
    CHECK(pager.stats().pixel_pages == 3);
    CHECK(pager.stats().accesses == 4);
    // Next pixel: A is resident, B (evicted in the last pixel) faults again
    // and brings its own bytes, not the frame's last page.
    pager.begin_pixel();
    CHECK(std::memcmp(pager.access(A), image.page(A).data(), 64) == 0);
    CHECK(pager.stats().misses == 3);
    CHECK(std::memcmp(pager.access(B), image.page(B).data(), 64) == 0);
    CHECK(std::memcmp(pager.access(B), image.page(B).data(), 64) == 0);
    CHECK(pager.stats().misses == 4);
    CHECK(std::memcmp(pager.access(A), image.page(A).data(), 64) == 0);
    pager.end_pixel();
    CHECK(pager.stats().misses == 5);
    CHECK(pager.stats().pixel_pages == 3 + 2);
    CHECK(pager.stats().accesses == 4 + 4);
  });
}

TEST_CASE("pager: a pixel touching more pages than its lists hold counts each once and reads each right") {
  // The list of pages touched in the pixel (kPagerTouchedCapacity) is
  // emptied when full, in the middle of the pixel: its pages leave the fast
  // path early and must come back through the page table without being
  // counted again.
  const testing::BuiltScene b = testing::build_spd("teapot", 8);
  const PagedImage image = build_paged_image(b.db, b.grid, 64);
  const std::uint32_t n = kPagerTouchedCapacity + 57;
  REQUIRE(image.layout.pages > 2 * n);
  auto home = [](std::uint32_t k) { return 2 * k; };  // pages homed at node 0
  with_two_nodes(image, 1, [&](Pager& pager, nodes::NodeContext&) {
    bool same = true;
    for (int pixel = 0; pixel < 2; ++pixel) {
      pager.begin_pixel();
      for (int round = 0; round < 2; ++round)
        for (std::uint32_t k = 0; k < n; ++k)
          same &= std::memcmp(pager.access(home(k)), image.page(home(k)).data(), 64) == 0;
      CHECK(pager.pixel_pages() == n);
    }
    pager.end_pixel();
    CHECK(same);
    CHECK(pager.stats().accesses == 4 * n);
    CHECK(pager.stats().pixel_pages == 2 * n);
    CHECK(pager.stats().misses == 0);
    CHECK(pager.stats().cache_accesses == 0);
    CHECK(pager.stats().lru_updates() == 0);
  });
}

TEST_CASE("pager: no LRU order while the cache has free frames, the last free frame builds it from the pixels") {
  // Cached pages are read like home pages until the cache is full; then
  // the order is each page's last pixel, and LRU evictions follow it.
  const testing::BuiltScene b = testing::build_spd("teapot", 2);
  const PagedImage image = build_paged_image(b.db, b.grid, 64);
  with_two_nodes(image, 3, [&](Pager& pager, nodes::NodeContext&) {
    auto same = [&](std::uint32_t p) { return std::memcmp(pager.access(p), image.page(p).data(), 64) == 0; };
    const std::uint32_t A = 1, B = 3, C = 5, D = 7, E = 9;  // homed at node 1
    pager.begin_pixel();
    CHECK(same(B));
    CHECK(same(A));  // fetched after B, touched in the same pixel
    pager.begin_pixel();
    CHECK(same(B));  // B is now more recent than A
    CHECK(same(B));
    CHECK(same(0));  // home
    pager.begin_pixel();
    CHECK(same(B));
    CHECK(!pager.lru_ordered());
    CHECK(pager.stats().misses == 2);
    CHECK(pager.stats().accesses == 6);
    CHECK(pager.stats().lru_updates() == 0);  // cached pages took the home pages' path
    pager.begin_pixel();
    CHECK(same(C));  // the last free frame: order A (pixel 1), B (pixel 3), C
    CHECK(pager.lru_ordered());
    CHECK(pager.stats().lru_order_frames == 3);
    CHECK(same(D));  // evicts A
    CHECK(!pager.resident(A));
    CHECK(pager.resident(B));
    pager.begin_pixel();
    CHECK(same(C));  // C after D now
    CHECK(same(E));  // evicts B
    CHECK(!pager.resident(B));
    CHECK(pager.resident(C));
    CHECK(pager.resident(D));
    CHECK(same(A));  // evicts D: C was touched in this pixel
    CHECK(!pager.resident(D));
    CHECK(pager.resident(C));
    pager.end_pixel();
    CHECK(pager.stats().misses == 6);
    CHECK(pager.stats().evictions == 3);
    CHECK(pager.stats().cache_misses == 3);  // D, E, A: C's fault filled the cache and built the order
    CHECK(pager.stats().cache_accesses == 4);  // D, C's touch, E, A
    CHECK(pager.stats().pixel_pages == 2 + 2 + 1 + 2 + 3);
  });
}

TEST_CASE("paged view: for_each_in_cell lists every cell, packed or not, while f() evicts the 1-page cache") {
  // f() reads each primitive, so with one cache frame every remote read
  // evicts the frame that held the cell's list piece or blocks.
  const testing::BuiltScene b = testing::build_spd("teapot", 2);
  // 512-byte pages: one block a page, cells chained over pages; 1024: pieces of up to 3 blocks;
  // 64: lists of 16 words a page, some with the header alone in its page's last word.
  for (const auto& [ps, pack] : {std::pair{64u, 0u}, std::pair{512u, 0u}, std::pair{512u, 1u}, std::pair{512u, 3u},
                                 std::pair{1024u, 0u}, std::pair{1024u, 1u}, std::pair{1024u, 3u}}) {
    CAPTURE(ps);
    CAPTURE(pack);
    const core::CellBlocks blocks = pack ? core::build_cell_blocks(b.db, b.grid, pack) : core::CellBlocks{};
    const PagedImage image = build_paged_image(b.db, b.grid, ps, pack ? &blocks : nullptr);
    if (pack) REQUIRE(image.layout.blocks > 0);
    if (ps == 64) {  // a header in its page's last word: the ids start on the next page
      std::uint32_t alone = 0;
      for (std::uint32_t c = 0; c < b.grid.info.cell_count(); ++c) {
        DirectoryEntry e;
        std::memcpy(&e, image.page(image.layout.directory_page(c)).data() + image.layout.directory_offset(c), 4);
        alone += e >= kListCell && (e & (ps - 1)) == ps - 4;
      }
      CHECK(alone > 0);
    }
    with_two_nodes(image, 1, [&](Pager& pager, nodes::NodeContext&) {
      const PagedView view(pager, b.grid.info, b.db.materials);
      for (std::uint32_t c = 0; c < b.grid.info.cell_count(); ++c) {
        pager.begin_pixel();
        std::vector<std::uint32_t> ids;
        const std::uint32_t empty = view.for_each_in_cell(c, [&](std::uint32_t id) {
          REQUIRE(std::memcmp(&view.primitive(id), &b.db.primitives[id], sizeof(core::Primitive)) == 0);
          ids.push_back(id);
        });
        const std::vector<std::uint32_t> expect(b.grid.cell_primitives.begin() + b.grid.cell_start[c],
                                                b.grid.cell_primitives.begin() + b.grid.cell_start[c + 1]);
        REQUIRE(ids == expect);
        REQUIRE(empty == (expect.empty() ? b.grid.empty_distance[c] : 0u));
      }
      CHECK(pager.stats().evictions > 0);
    });
  }
}
