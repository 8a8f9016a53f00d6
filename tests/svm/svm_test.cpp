#include <doctest/doctest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <stdexcept>
#include <string>
#include <random>
#include <tuple>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/render.h"
#include "svm/svm.h"
#include "test_grid_params.h"
#include "test_scenes.h"

using namespace raynode;
using namespace raynode::svm;

namespace {

SvmParams small_params(std::uint32_t nodes, std::uint32_t cache) {
  SvmParams p;
  p.render.width = 24;
  p.render.height = 18;
  p.machine.nodes = nodes;
  p.machine.node_memory = 4 * nodes::kMiB;
  p.machine.timeout_s = 120;
  p.cache_pages = cache;
  return p;
}

/// A tessellated teapot whose triangles lie in random order (`seed`), as an
/// exported mesh's may; its grid is left for the caller to build.
testing::BuiltScene shuffled_teapot(unsigned seed) {
  testing::BuiltScene b = testing::build_spd("teapot", 3);
  std::mt19937 rng(seed);
  std::shuffle(b.db.primitives.begin(), b.db.primitives.end(), rng);
  return b;
}

}  // namespace

TEST_CASE("svm: images are bit-identical to sequential for N in {1,2,3,4,7,16,64} and caches of 1, 3 and all pages") {
  struct Case {
    const char* name;
    int size, tessellate;
  };
  for (const Case c : {Case{"teapot", 2, 0}, Case{"rings", 1, 0}, Case{"mount", 2, 2}, Case{"tetra", 3, 0},
                       Case{"balls", 1, 0}}) {
    const testing::BuiltScene b = testing::build_spd(c.name, c.size, c.tessellate);
    core::RenderParams rp = small_params(1, 0).render;
    const core::RenderResult seq = core::render(b.db, b.grid, rp);
    for (std::uint32_t n : {1u, 2u, 3u, 4u, 7u, 16u, 64u})
      for (std::uint32_t cache : {1u, 3u, 0u}) {
        if (n == 1 && cache != 0) continue;  // one node holds every page at home
        CAPTURE(c.name);
        CAPTURE(n);
        CAPTURE(cache);
        SvmParams p = small_params(n, cache);
        p.page_size = 256;  // more pages than nodes, even for the small scenes
        const SvmResult r = render_svm(b.db, b.grid, p);
        CHECK(testing::same_bytes(r.render.color, seq.color));
        CHECK(r.render.stats.rays.total() == seq.stats.rays.total());
        const PagerStats t = r.pager_total();
        CHECK(t.pixels == std::uint64_t(rp.width * rp.height));
        if (n > 1 && cache == 1) CHECK(t.evictions > 0);
        if (cache == 0) CHECK(t.evictions == 0);
      }
  }
}

TEST_CASE("svm: with half or nearest work grants (--work-grants), or requests off, images stay bit-identical to sequential") {
  for (const auto& [name, size, tessellate] : {std::tuple{"teapot", 2, 0}, std::tuple{"tetra", 3, 0}}) {
    const testing::BuiltScene b = testing::build_spd(name, size, tessellate);
    core::RenderParams rp = small_params(1, 0).render;
    rp.width = rp.height = 40;
    const core::RenderResult seq = core::render(b.db, b.grid, rp);
    // Nearest grants with the route they are meant for (a request carries
    // the requester's last item to the node that granted it).
    for (const auto& [grant, route] : {std::pair{nodes::WorkGrant::kHalf, nodes::WorkRequestRoute::kRing},
                                       std::pair{nodes::WorkGrant::kHalf, nodes::WorkRequestRoute::kLastGrantor},
                                       std::pair{nodes::WorkGrant::kNearest, nodes::WorkRequestRoute::kLastGrantor},
                                       std::pair{nodes::WorkGrant::kItem, nodes::WorkRequestRoute::kOff}})
      for (std::uint32_t n : {3u, 16u, 64u})
        for (std::uint32_t cache : {1u, 0u}) {
          CAPTURE(name);
          CAPTURE(nodes::work_grant_name(grant));
          CAPTURE(nodes::work_request_route_name(route));
          CAPTURE(n);
          CAPTURE(cache);
          SvmParams p = small_params(n, cache);
          p.render = rp;
          p.page_size = 256;
          p.machine.work_grant = grant;
          p.machine.work_request_route = route;
          const SvmResult r = render_svm(b.db, b.grid, p);
          CHECK(r.run.work_grants == nodes::work_grant_name(grant));
          CHECK(testing::same_bytes(r.render.color, seq.color));
          CHECK(r.pager_total().pixels == std::uint64_t(rp.width * rp.height));
          control::WorkStats w;
          for (const control::WorkStats& s : r.work) w += s;
          CHECK(w.pixels == std::uint64_t(rp.width * rp.height));
          CHECK(w.items_received >= w.grants_given);
          if (route == nodes::WorkRequestRoute::kOff) CHECK(w.requests_sent + w.grants_given == 0);
        }
  }
}

TEST_CASE("svm: balanced submaps (--submaps balanced) keep the sequential image for every node count and cache") {
  const testing::BuiltScene b = testing::build_spd("tetra", 3);
  core::RenderParams rp = small_params(1, 0).render;
  rp.width = rp.height = 40;
  const core::RenderResult seq = core::render(b.db, b.grid, rp);
  for (std::uint32_t n : {2u, 7u, 16u, 64u})
    for (std::uint32_t cache : {1u, 0u}) {
      CAPTURE(n);
      CAPTURE(cache);
      SvmParams p = small_params(n, cache);
      p.render = rp;
      p.page_size = 256;
      p.submaps.rule = control::SubmapRule::kBalanced;
      const SvmResult r = render_svm(b.db, b.grid, p);
      CHECK(testing::same_bytes(r.render.color, seq.color));
      CHECK(r.pager_total().pixels == std::uint64_t(rp.width * rp.height));
      REQUIRE(r.submaps.rects.size() == n);
      std::int64_t area = 0;
      for (const control::Rect& m : r.submaps.rects) area += m.area();
      CHECK(area == std::int64_t(rp.width) * rp.height);
      CHECK(r.submaps.estimate.pixels == 5u * 5u);  // one per 8x8 block
      CHECK(r.submaps.estimate.rays >= r.submaps.estimate.pixels);
    }
}

TEST_CASE("svm --pack-cells: paged triangle blocks give the sequential image for every node count and cache") {
  // 512-byte pages hold one block each, so every packed cell of more than 8
  // triangles is visited in pieces, and a 1-page cache evicts between them.
  for (const auto& [name, size, tessellate] : {std::tuple{"teapot", 2, 0}, std::tuple{"mount", 2, 2},
                                              std::tuple{"tetra", 3, 0}, std::tuple{"rings", 1, 0}}) {
    const testing::BuiltScene b = testing::build_spd(name, size, tessellate);
    core::RenderParams rp = small_params(1, 0).render;
    const core::RenderResult seq = core::render(b.db, b.grid, rp);
    for (std::uint32_t pack : {1u, 3u}) {
      const std::size_t blocks = core::build_cell_blocks(b.db, b.grid, pack).blocks.size();
      if (pack == 1) REQUIRE(blocks > 0);  // every scene has triangle-only cells
      for (std::uint32_t n : {1u, 2u, 7u})
        for (std::uint32_t cache : {1u, 3u, 0u}) {
          if (n == 1 && cache != 0) continue;
          CAPTURE(std::string(name));
          CAPTURE(pack);
          CAPTURE(n);
          CAPTURE(cache);
          SvmParams p = small_params(n, cache);
          p.page_size = 512;
          p.pack_min = pack;
          const SvmResult r = render_svm(b.db, b.grid, p);
          CHECK(r.layout.blocks == blocks);
          CHECK(testing::same_bytes(r.render.color, seq.color));
          CHECK(r.render.stats.rays.total() == seq.stats.rays.total());
        }
    }
  }
}

TEST_CASE("svm: AOVs are identical to sequential's, the node map names a working node for every pixel") {
  const testing::BuiltScene b = testing::build_spd("teapot", 2);
  SvmParams p = small_params(5, 2);
  p.render.depth_aov = p.render.normal_aov = p.render.primitive_aov = true;
  p.node_aov = p.pages_aov = true;
  const core::RenderResult seq = core::render(b.db, b.grid, p.render);
  const SvmResult r = render_svm(b.db, b.grid, p);
  CHECK(testing::same_bytes(r.render.color, seq.color));
  CHECK(testing::same_bytes(r.render.depth, seq.depth));
  CHECK(testing::same_bytes(r.render.normal, seq.normal));
  CHECK(testing::same_bytes(r.render.primitive, seq.primitive));
  std::vector<std::uint64_t> pixels_of(5, 0);
  double pages_sum = 0;
  for (int y = 0; y < p.render.height; ++y)
    for (int x = 0; x < p.render.width; ++x) {
      const float id = *r.node.at(x, y);
      REQUIRE(id >= 0);
      REQUIRE(id < 5);
      ++pixels_of[std::size_t(id)];
      const float pages = *r.pages.at(x, y);
      REQUIRE(pages >= 0);
      if (std::isfinite(*r.render.depth.at(x, y))) REQUIRE(pages >= 3);  // a hit: directory, list, primitive
      pages_sum += pages;
    }
  // Each node's pixels in the map are the pixels it rendered. (Which nodes
  // render how many follows the node threads' timing: a node started late
  // may have had its items stolen, so no node count is asserted.)
  std::size_t working = 0;
  for (std::size_t i = 0; i < 5; ++i) {
    CAPTURE(i);
    CHECK(pixels_of[i] == r.work[i].pixels);
    working += pixels_of[i] > 0;
  }
  CHECK(working >= 2);
  const PagerStats t = r.pager_total();
  CHECK(pages_sum == double(t.pixel_pages));
}

TEST_CASE("svm: the tracer's page accesses do not depend on node count or cache, faults do, and every fault is served") {
  const testing::BuiltScene b = testing::build_spd("rings", 1);
  std::uint64_t accesses = 0, pixel_pages = 0, misses_small = 0, misses_big = 0;
  for (std::uint32_t n : {1u, 4u, 9u})
    for (std::uint32_t cache : {1u, 0u}) {
      if (n == 1 && cache == 1) continue;
      SvmParams p = small_params(n, cache);
      p.page_size = 128;
      p.directory_order = DirectoryOrder::kLinear;  // the distinct pages depend on the order (next test)
      const SvmResult r = render_svm(b.db, b.grid, p);
      const PagerStats t = r.pager_total();
      if (accesses == 0) accesses = t.accesses, pixel_pages = t.pixel_pages;
      // Without evictions the accesses are the tracer's own; with them a
      // cell's list page is found again after each eviction (more accesses),
      // but the distinct pages per pixel stay the same.
      if (cache == 0) CHECK(t.accesses == accesses);
      else CHECK(t.accesses >= accesses);
      CHECK(t.pixel_pages == pixel_pages);
      CHECK(t.misses == t.requests_served);
      std::uint64_t by_segment = 0;
      for (std::uint64_t m : t.segment_misses) by_segment += m;
      CHECK(by_segment == t.misses);
      if (n == 9) {  // rings: every ray reads cells, lists and spheres
        CHECK(t.segment_misses[std::size_t(Segment::kDirectory)] > 0);
        CHECK(t.segment_misses[std::size_t(Segment::kLists)] > 0);
        CHECK(t.segment_misses[std::size_t(Segment::kPrimitives)] > 0);
        CHECK(t.segment_misses[std::size_t(Segment::kBlocks)] == 0);  // no packed cells
      }
      if (cache == 0)  // each page at most once per node: a segment's faults are at most its pages per node
        CHECK(t.segment_misses[std::size_t(Segment::kDirectory)] <= std::uint64_t(n - 1) * r.layout.directory_pages);
      const nodes::NodeCounters total = r.run.total();
      CHECK(total.sent[std::size_t(nodes::MessageType::kPageRequest)].messages == t.misses);
      CHECK(total.received[std::size_t(nodes::MessageType::kPageReply)].bytes == t.misses * (128 + 4));
      if (n == 1) CHECK(t.misses == 0);
      if (n == 9 && cache == 1) misses_small = t.misses;
      if (n == 9 && cache == 0) misses_big = t.misses;
      if (cache == 0)  // a cache that holds everything fetches each page at most once per node
        for (std::size_t i = 0; i < r.pager.size(); ++i) CHECK(r.pager[i].misses <= r.layout.pages - r.pager[i].home_pages);
    }
  CHECK(misses_small > misses_big);
}

TEST_CASE("svm: a bricked cell directory gives the sequential image with fewer directory faults and pages per pixel") {
  const testing::BuiltScene b = testing::build_spd("tetra", 4);
  core::RenderParams rp = small_params(1, 0).render;
  rp.width = rp.height = 48;
  const core::RenderResult seq = core::render(b.db, b.grid, rp);
  PagerStats linear_16, bricked_16;
  for (const DirectoryOrder order : {DirectoryOrder::kLinear, DirectoryOrder::kBricked})
    for (std::uint32_t n : {1u, 16u}) {
      CAPTURE(directory_order_name(order));
      CAPTURE(n);
      SvmParams p = small_params(n, 0);
      p.render = rp;
      p.page_size = 128;  // 32 cells a page: many directory pages even for a small grid
      p.directory_order = order;
      // Static submaps only: with work requests, which node renders which
      // pixel follows the host's thread scheduling, and so do the faults
      // (at 48x48 under a loaded CI run the two layouts' counts once
      // crossed: bricked 137 against linear 122 directory faults). With
      // the requests off each node renders its own submap, the cache holds
      // every page, and the counts are the same on every run.
      p.machine.work_request_route = nodes::WorkRequestRoute::kOff;
      const SvmResult r = render_svm(b.db, b.grid, p);
      if (n == 16) {  // ... which this checks: a second run faults the same pages
        const PagerStats again = render_svm(b.db, b.grid, p).pager_total();
        CHECK(again.misses == r.pager_total().misses);
        CHECK(again.pixel_pages == r.pager_total().pixel_pages);
      }
      CHECK(testing::same_bytes(r.render.color, seq.color));
      CHECK(r.layout.directory_order == order);
      CHECK(r.to_json()["directory_order"] == directory_order_name(order));
      if (order == DirectoryOrder::kBricked) {
        const core::CellBricks& k = r.layout.bricks;
        CHECK(k.cells() <= int(r.layout.page_size / sizeof(DirectoryEntry)));
        CHECK(r.layout.directory_pages ==
              k.bricks(b.grid.info, 0) * k.bricks(b.grid.info, 1) * k.bricks(b.grid.info, 2));
      }
      if (n == 16) (order == DirectoryOrder::kLinear ? linear_16 : bricked_16) = r.pager_total();
    }
  // The tracer reads the same entries, from fewer pages.
  CHECK(bricked_16.accesses == linear_16.accesses);
  CHECK(bricked_16.segment_misses[std::size_t(Segment::kDirectory)] <
        linear_16.segment_misses[std::size_t(Segment::kDirectory)]);
  CHECK(bricked_16.pixel_pages < linear_16.pixel_pages);
  // auto: bricked on more than one node, linear on one.
  SvmParams p = small_params(4, 0);
  p.render.width = p.render.height = 8;
  CHECK(render_svm(b.db, b.grid, p).layout.directory_order == DirectoryOrder::kBricked);
  p.machine.nodes = 1;
  CHECK(render_svm(b.db, b.grid, p).layout.directory_order == DirectoryOrder::kLinear);
}

TEST_CASE("svm: page faults cost virtual time under a network model, booked as communication") {
  const testing::BuiltScene b = testing::build_spd("teapot", 2);
  SvmParams p = small_params(4, 2);
  p.machine.network = nodes::make_network("ipsc2", 1e-2);  // ~1 ms latency: far above the CPU time of a fault
  const SvmResult r = render_svm(b.db, b.grid, p);
  const nodes::NodeCounters total = r.run.total();
  const PagerStats t = r.pager_total();
  REQUIRE(t.misses > 0);
  // Each fault waits at least a request's and a reply's transfer time.
  const double min_wait = 2 * p.machine.network.latency_s;
  CHECK(total.communication_s >= 0.99 * double(t.misses) * min_wait);
}

TEST_CASE("svm: under the model clock a fault's own work costs the network's fault_s, else the cost model's") {
  const testing::BuiltScene b = testing::build_spd("teapot", 2);
  const double big = 1e-3;  // far above the tracing of this small render
  for (const bool network_says : {true, false}) {
    CAPTURE(network_says);
    SvmParams p = small_params(4, 2);
    p.machine.clock = nodes::ComputeClock::kModel;
    p.machine.network = nodes::make_network("none");
    if (network_says) p.machine.network.fault_s = big;
    else p.machine.cost_model.unit_s[std::size_t(core::CostFeature::kPageFault)] = big / 1e4;
    const SvmResult r = render_svm(b.db, b.grid, p);
    const double misses = double(r.pager_total().misses);
    REQUIRE(misses > 0);
    const double busy = r.run.total().busy_s;
    if (network_says) {
      CHECK(busy >= misses * big);
      CHECK(busy < misses * big * 1.5);
    } else {
      CHECK(busy >= misses * big / 1e4);
      CHECK(busy < misses * big * 0.5);
    }
  }
}

TEST_CASE("svm: under the model clock each access to a cached page costs the network's cache_access_s or the cost model's") {
  const testing::BuiltScene b = testing::build_spd("teapot", 2);
  const double big = 1e-4;  // far above the tracing of one access
  for (const std::uint32_t nodes : {1u, 2u, 4u}) {
    CAPTURE(nodes);
    double busy[4] = {};
    PagerStats t[4];
    // 0: not priced; 1: by the network; 2: by the cost model's unit cost;
    // 3: the cost model's, which the network's 0 overrides.
    for (const int priced : {0, 1, 2, 3}) {
      SvmParams p = small_params(nodes, 0);
      p.machine.clock = nodes::ComputeClock::kModel;
      p.machine.network = nodes::make_network("none");
      REQUIRE(p.machine.network.cache_access_s < 0);  // unset: the cost model's
      if (priced == 1) p.machine.network.cache_access_s = big;
      if (priced == 3) p.machine.network.cache_access_s = 0.0;
      p.machine.cost_model.unit_s[std::size_t(core::CostFeature::kCachePageAccess)] = priced >= 2 ? big : 0.0;
      const SvmResult r = render_svm(b.db, b.grid, p);
      busy[priced] = r.run.total().busy_s;
      t[priced] = r.pager_total();
    }
    // Runs of more than one node share their work out differently each time:
    // alike within 1%, where pricing the accesses adds many times busy[0] (below).
    CHECK(busy[3] == doctest::Approx(busy[0]).epsilon(0.01));

    for (const int priced : {1, 2}) {
      CAPTURE(priced);
      if (nodes == 1) {  // every page is home: nothing to price, the same virtual time
        CHECK(t[priced].cache_page_accesses == 0);
        CHECK(busy[priced] == doctest::Approx(busy[0]).epsilon(1e-9));
        continue;
      }
      // Node by node, pages are cached that another node is home of: every
      // access to them is priced, and only those (home pages are not).
      REQUIRE(t[priced].cache_page_accesses > t[priced].misses);
      CHECK(t[priced].cache_page_accesses < t[priced].accesses);
      const double priced_s = double(t[priced].cache_page_accesses) * big;
      CHECK(busy[priced] >= priced_s + 0.5 * busy[0]);
      CHECK(busy[priced] <= priced_s + 2.0 * busy[0]);
    }
  }
}

TEST_CASE("svm: a database too big for the nodes stops at once, naming the sizes") {
  const testing::BuiltScene b = testing::build_spd("tetra", 5);
  SvmParams p = small_params(2, 0);
  p.machine.node_memory = 128 * 1024;
  CHECK_THROWS_WITH_AS(render_svm(b.db, b.grid, p), doctest::Contains("database needs"), std::runtime_error);
  CHECK_THROWS_WITH_AS(render_svm(b.db, b.grid, p), doctest::Contains("2 nodes x 128 KiB hold"), std::runtime_error);
  // With enough nodes the same memory suffices.
  p.machine.nodes = 64;
  p.machine.mailbox_capacity = 16;
  CHECK_NOTHROW(render_svm(b.db, b.grid, p));
}

TEST_CASE("svm: a requested cache that does not fit is refused with the sizes, a fraction above 1 is refused") {
  const testing::BuiltScene b = testing::build_spd("tetra", 6);
  SvmParams p = small_params(4, 300);
  p.machine.node_memory = 256 * 1024;
  CHECK_THROWS_WITH_AS(render_svm(b.db, b.grid, p), doctest::Contains("does not fit"), std::runtime_error);
  p.cache_pages = 0;
  p.cache_fraction = 1.5;
  CHECK_THROWS_AS(render_svm(b.db, b.grid, p), std::invalid_argument);
}

TEST_CASE("svm: the default cache takes the memory left and fits in it, to the byte") {
  // Nodes too small to cache every page: the cache is sized from the
  // memory left after the fixed parts and the pager's per-frame overhead
  // (an overhead counted short makes the render fail to allocate).
  const testing::BuiltScene b = testing::build_spd("tetra", 8);
  const core::RenderResult seq = core::render(b.db, b.grid, small_params(1, 0).render);
  for (std::size_t memory : {std::size_t(4) << 20, (std::size_t(5) << 20) + 17}) {
    CAPTURE(memory);
    SvmParams p = small_params(4, 0);
    p.machine.node_memory = memory;
    const SvmResult r = render_svm(b.db, b.grid, p);
    CHECK(testing::same_bytes(r.render.color, seq.color));
    for (const PagerStats& s : r.pager) {
      CHECK(s.cache_pages > 0);
      CHECK(s.cache_pages < r.layout.pages - s.home_pages);  // limited by memory, not by the database
    }
  }
}

TEST_CASE("svm: cache given as a fraction of the database's pages") {
  const testing::BuiltScene b = testing::build_spd("rings", 1);
  SvmParams p = small_params(4, 0);
  p.page_size = 128;
  p.cache_fraction = 0.1;
  const SvmResult r = render_svm(b.db, b.grid, p);
  const std::uint32_t want = std::uint32_t(std::ceil(0.1 * r.layout.pages));
  for (const PagerStats& s : r.pager) CHECK(s.cache_pages == std::min(want, r.layout.pages - s.home_pages));
}

TEST_CASE("svm: node threads cannot read the host's page image during the render (it is protected)") {
  const testing::BuiltScene b = testing::build_spd("teapot", 2);
  for (const bool cheat : {false, true}) {
    CAPTURE(cheat);
    const pid_t pid = fork();
    REQUIRE(pid >= 0);
    if (pid == 0) {
      std::signal(SIGSEGV, SIG_DFL);  // die of it (doctest would catch it)
      SvmParams p = small_params(2, 0);
      p.debug_read_host_image = cheat;
      try {
        render_svm(b.db, b.grid, p);
      } catch (...) {
        _exit(3);
      }
      _exit(0);
    }
    int status = 0;
    REQUIRE(waitpid(pid, &status, 0) == pid);
    if (cheat) {
      CHECK(WIFSIGNALED(status));
      if (WIFSIGNALED(status)) CHECK(WTERMSIG(status) == SIGSEGV);
    } else {
      CHECK(WIFEXITED(status));
      if (WIFEXITED(status)) CHECK(WEXITSTATUS(status) == 0);
    }
  }
}

TEST_CASE("svm: under the model clock with the ipsc2 network every node count finishes with the sequential image") {
  // Regression: a node awaiting a page held the others back while a node
  // queued for its permit after a fault set aside the awaiting node's work
  // request — a deadlock at 16 nodes. Faults resume with the next free permit.
  const testing::BuiltScene b = testing::build_spd("teapot", 3);
  core::RenderParams rp = small_params(1, 0).render;
  const core::RenderResult seq = core::render(b.db, b.grid, rp);
  for (std::uint32_t n : {4u, 16u, 64u})
    for (std::uint32_t cache : {3u, 0u}) {
      CAPTURE(n);
      CAPTURE(cache);
      SvmParams p = small_params(n, cache);
      p.page_size = 256;
      p.machine.clock = nodes::ComputeClock::kModel;
      p.machine.network = nodes::make_network("ipsc2", 1e-6);
      const SvmResult r = render_svm(b.db, b.grid, p);
      CHECK(testing::same_bytes(r.render.color, seq.color));
      CHECK(r.pager_total().misses > 0);
      double busy = 0;
      for (const nodes::NodeReport& node : r.run.nodes) busy += node.counters.busy_s;
      CHECK(r.run.parallel_time_s >= busy / double(n) * (1 - 1e-9));
      CHECK(r.run.total().communication_s > 0);
    }
}

TEST_CASE("svm over an adaptive grid: paged sub-grids give the sequential image for every order, packing, node count and cache") {
  // A coarse top grid with sub-grids from 4 primitives (two levels below
  // the top), and the default adaptive grid on a small mesh standing on a
  // floor 300 times its size: the floor beside the top grid (its leaf's
  // key in the replicated layout), and, kept in the top grid, beside the
  // sub-grid of the mesh's cell (core::SubGrid::large_list).
  const core::GridParams deep = raynode::testing::small_scene_sub_grids(4, true);
  core::GridParams normal;
  normal.kind = core::GridKind::kAdaptive;
  core::GridParams in_top = normal;
  in_top.large_beside_top = false;
  std::vector<std::pair<testing::BuiltScene, core::GridParams>> scenes;
  scenes.emplace_back(testing::build_spd("teapot", 2), deep);
  scenes.emplace_back(testing::build_spd("tetra", 3), deep);
  for (const core::GridParams& gp : {normal, in_top}) {
    core::Scene s = core::make_spd_scene(core::SpdParams{"tetra", 5, 0});
    const float f = 300.0f;
    const core::Vec3 quad[4] = {{-f, -f, -1.01f}, {f, -f, -1.01f}, {f, f, -1.01f}, {-f, f, -1.01f}};
    s.add_polygon(quad, 4);
    testing::BuiltScene b;
    b.db = core::make_database(s);
    scenes.emplace_back(std::move(b), gp);
  }
  int large_lists = 0, top_large_lists = 0;
  for (auto& [b, gp] : scenes) {
    b.grid = core::build_grid(b.db, gp);
    const bool top_large = !b.grid.sub_grids.empty() && b.grid.sub_grids[0].large_list;
    REQUIRE((b.grid.sub_grid_count() > 0 || top_large));
    top_large_lists += top_large;
    for (std::size_t i = 1; i < b.grid.sub_grids.size(); ++i) large_lists += b.grid.sub_grids[i].large_list;
    core::RenderParams rp = small_params(1, 0).render;
    const core::RenderResult seq = core::render(b.db, b.grid, rp);
    const core::RenderResult uniform = core::render(b.db, core::build_grid(b.db), rp);
    CHECK(testing::same_bytes(seq.color, uniform.color));
    for (const DirectoryOrder order : {DirectoryOrder::kLinear, DirectoryOrder::kBricked})
      for (std::uint32_t pack : {0u, 1u})
        for (std::uint32_t n : {1u, 3u, 16u})
          for (std::uint32_t cache : {1u, 0u}) {
            if (n == 1 && cache != 0) continue;
            CAPTURE(b.db.primitives.size());
            CAPTURE(directory_order_name(order));
            CAPTURE(pack);
            CAPTURE(n);
            CAPTURE(cache);
            SvmParams p = small_params(n, cache);
            p.page_size = 512;  // one packed block a page
            p.pack_min = pack;
            p.directory_order = order;
            const SvmResult r = render_svm(b.db, b.grid, p);
            CHECK(r.layout.sub_grids == b.grid.sub_grids.size());
            CHECK((r.layout.top_large_key != core::kNoLeaf) == top_large);
            CHECK(testing::same_bytes(r.render.color, seq.color));
            CHECK(r.render.stats.rays.total() == seq.stats.rays.total());
            CHECK(r.render.stats.traversal.cells_visited == seq.stats.traversal.cells_visited);
            if (n > 1 && cache == 1 && b.grid.sub_grid_count() > 0)
              CHECK(r.pager_total().segment_misses[std::size_t(Segment::kSubGrids)] > 0);
          }
  }
  CHECK(large_lists > 0);
  CHECK(top_large_lists > 0);
}

TEST_CASE("svm: primitives in cell order give the sequential image and, on a shuffled mesh, fewer pages per pixel") {
  // File order scatters a cell's triangles over many pages.
  testing::BuiltScene b = shuffled_teapot(7);
  b.grid = core::build_grid(b.db, raynode::testing::small_scene_sub_grids(16, false));  // sub-grids even on this small mesh
  REQUIRE(b.grid.sub_grid_count() > 0);
  core::RenderParams rp = small_params(1, 0).render;
  rp.width = rp.height = 40;
  const core::RenderResult seq = core::render(b.db, b.grid, rp);
  PagerStats file, cell;
  for (const std::uint32_t pack : {0u, 3u})
    for (const PrimitiveOrder order : {PrimitiveOrder::kFile, PrimitiveOrder::kCell}) {
      CAPTURE(pack);
      CAPTURE(primitive_order_name(order));
      SvmParams p = small_params(4, 0);
      p.render = rp;
      p.page_size = 1024;
      p.pack_min = pack;
      p.primitive_order = order;
      p.machine.work_request_route = nodes::WorkRequestRoute::kOff;  // each node its own submap: repeatable faults
      const SvmResult r = render_svm(b.db, b.grid, p);
      CHECK(testing::same_bytes(r.render.color, seq.color));
      CHECK(r.render.stats.rays.total() == seq.stats.rays.total());
      CHECK(r.layout.primitive_order == order);
      CHECK(r.to_json()["primitive_order"] == primitive_order_name(order));
      if (pack == 0) (order == PrimitiveOrder::kFile ? file : cell) = r.pager_total();
    }
  // The tracer reads the same objects, from fewer primitive pages.
  CHECK(cell.accesses == file.accesses);
  CHECK(cell.pixel_pages * 3 < file.pixel_pages * 2);
  CHECK(cell.segment_misses[std::size_t(Segment::kPrimitives)] < file.segment_misses[std::size_t(Segment::kPrimitives)]);
  // auto: over the adaptive grid the order whose cell lists name fewer
  // pages (here cell order, the file's being random); over the uniform
  // grid file order, the paper's layout.
  SvmParams p = small_params(2, 0);
  p.render.width = p.render.height = 8;
  CHECK(render_svm(b.db, b.grid, p).layout.primitive_order == PrimitiveOrder::kCell);
  const core::Grid uniform = core::build_grid(b.db);
  CHECK(render_svm(b.db, uniform, p).layout.primitive_order == PrimitiveOrder::kFile);
}

TEST_CASE("svm: auto primitive order takes the order whose cell lists name fewer pages by area, file order on a spatial file") {
  core::GridParams gp;
  gp.kind = core::GridKind::kAdaptive;
  // Tetra's file order is its recursion's, spatial at every scale; the
  // shuffled teapot's is random.
  testing::BuiltScene tetra = testing::build_spd("tetra", 5);
  tetra.grid = core::build_grid(tetra.db, gp);
  testing::BuiltScene teapot = shuffled_teapot(11);
  teapot.grid = core::build_grid(teapot.db, gp);
  for (const testing::BuiltScene* b : {&tetra, &teapot}) {
    // The leaf weights: half the surface of each leaf's box; a large-
    // primitive leaf weighs what its sub-grid's box does.
    const std::vector<double> w = leaf_weights(b->grid);
    REQUIRE(w.size() == b->grid.leaf_cells());
    const auto half_area = [](const core::Vec3& e) { return double(e.x) * e.y + double(e.y) * e.z + double(e.z) * e.x; };
    for (std::size_t i = 0; i < b->grid.sub_grids.size(); ++i) {
      const core::SubGrid& s = b->grid.sub_grids[i];
      for (std::uint32_t c = 0; c < s.info.cell_count(); ++c)
        if (!(b->grid.cell_entries[s.first_entry + c] & core::kSubGridEntry))
          CHECK(w[s.first_entry + c] == doctest::Approx(half_area(s.info.cell_size)));
      if (s.large_list) CHECK(w[s.first_entry + s.info.cell_count()] == doctest::Approx(half_area(s.info.bounds.extent())));
    }
    // The two sums, worked out here from the lists and the slots.
    PageLayout l = make_page_layout(b->db, b->grid, 1024, nullptr, DirectoryOrder::kBricked);
    double pages[2] = {0, 0};
    for (const PrimitiveOrder order : {PrimitiveOrder::kFile, PrimitiveOrder::kCell}) {
      l.primitive_order = order;
      const std::vector<std::uint32_t> slot = primitive_slots(l, b->grid, l.primitives);
      for (std::uint32_t c = 0; c < b->grid.leaf_cells(); ++c) {
        std::vector<bool> seen(l.primitive_pages, false);
        for (std::uint32_t k = b->grid.cell_start[c]; k < b->grid.cell_start[c + 1]; ++k) {
          const std::uint32_t page = slot[b->grid.cell_primitives[k]] / 16;  // 16 records a page
          if (!seen[page]) pages[std::size_t(order)] += w[c];
          seen[page] = true;
        }
      }
      CHECK(list_primitive_pages(b->grid, w, slot, l.primitive_shift) == doctest::Approx(pages[std::size_t(order)]));
    }
    const PrimitiveOrder fewer = pages[1] < pages[0] ? PrimitiveOrder::kCell : PrimitiveOrder::kFile;
    CHECK(fewer_list_pages(b->grid, l) == fewer);
    SvmParams p = small_params(4, 0);
    p.render.width = p.render.height = 8;
    CHECK(render_svm(b->db, b->grid, p).layout.primitive_order == fewer);
  }
  CHECK(fewer_list_pages(tetra.grid, make_page_layout(tetra.db, tetra.grid, 1024, nullptr, DirectoryOrder::kBricked)) ==
        PrimitiveOrder::kFile);
  CHECK(fewer_list_pages(teapot.grid, make_page_layout(teapot.db, teapot.grid, 1024, nullptr, DirectoryOrder::kBricked)) ==
        PrimitiveOrder::kCell);
}
