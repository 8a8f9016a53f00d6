// Every node mode under exhausted resources: 1-page caches (svm), 1-slot
// mailboxes (every mode; dataflow's --queue-capacity), more nodes than
// pixels, a 1x1 image. Each run must finish (a watchdog turns a hang into a
// failure) with the sequential image: byte-identical for replicated and svm,
// within 1e-5 per channel for dataflow (its contributions add up in arrival
// order), and with AOVs identical in every mode.
#include <doctest/doctest.h>

#include <cstdint>

#include "core/render.h"
#include "dataflow/dataflow.h"
#include "control/replicated.h"
#include "robustness/compare.h"
#include "svm/svm.h"
#include "test_scenes.h"

using namespace raynode;
using robustness::max_diff;
using testing::same_bytes;

namespace {

core::RenderParams tiny(int width, int height) {
  core::RenderParams rp;
  rp.width = width;
  rp.height = height;
  rp.depth_aov = rp.normal_aov = rp.primitive_aov = true;
  return rp;
}

nodes::MachineParams machine(std::uint32_t nodes, std::uint32_t mailbox_capacity = 0) {
  nodes::MachineParams m;
  m.nodes = nodes;
  m.node_memory = 8 * nodes::kMiB;
  m.mailbox_capacity = mailbox_capacity;
  m.timeout_s = 120;  // a hang fails the test instead of blocking the suite
  return m;
}

void check_aovs_equal(const core::RenderResult& r, const core::RenderResult& seq) {
  CHECK(same_bytes(r.depth, seq.depth));
  CHECK(same_bytes(r.normal, seq.normal));
  CHECK(same_bytes(r.primitive, seq.primitive));
}

control::ReplicatedResult run_replicated(const testing::BuiltScene& b, const core::RenderParams& rp,
                                       std::uint32_t n, std::uint32_t mailbox = 0) {
  control::ReplicatedParams p;
  p.render = rp;
  p.machine = machine(n, mailbox);
  p.item_w = p.item_h = 1;
  return control::render_replicated(b.db, b.grid, p);
}

svm::SvmResult run_svm(const testing::BuiltScene& b, const core::RenderParams& rp, std::uint32_t n,
                       std::uint32_t cache, std::uint32_t page_size, std::uint32_t mailbox = 0) {
  svm::SvmParams p;
  p.render = rp;
  p.machine = machine(n, mailbox);
  p.cache_pages = cache;
  p.page_size = page_size;
  p.item_w = p.item_h = 1;
  return svm::render_svm(b.db, b.grid, p);
}

dataflow::DataflowResult run_dataflow(const testing::BuiltScene& b, const core::RenderParams& rp, std::uint32_t n,
                                      std::uint32_t queue_capacity) {
  dataflow::DataflowParams p;
  p.render = rp;
  p.machine = machine(n, queue_capacity);
  p.machine.node_memory = 16 * nodes::kMiB;
  p.send_queue_slots = queue_capacity;  // as small a sending queue: small queues spill
  return dataflow::render_dataflow(b.db, b.grid, p);
}

}  // namespace

TEST_CASE("exhausted: 64 nodes on a 4x4 image (more nodes than pixels) give the sequential image in every mode") {
  const testing::BuiltScene b = testing::build_spd("rings", 1);
  const core::RenderParams rp = tiny(4, 4);
  const core::RenderResult seq = core::render(b.db, b.grid, rp);
  REQUIRE(seq.stats.rays.primary == 16);
  {
    const control::ReplicatedResult r = run_replicated(b, rp, 64);
    CHECK(same_bytes(r.render.color, seq.color));
    check_aovs_equal(r.render, seq);
    CHECK(r.render.stats.rays.total() == seq.stats.rays.total());
    std::uint64_t pixels = 0;
    for (const control::WorkStats& w : r.work) pixels += w.pixels;
    CHECK(pixels == 16);
  }
  {
    const svm::SvmResult r = run_svm(b, rp, 64, 1, 64);  // 1-page caches, the smallest pages
    CHECK(same_bytes(r.render.color, seq.color));
    check_aovs_equal(r.render, seq);
    CHECK(r.render.stats.rays.total() == seq.stats.rays.total());
    CHECK(r.pager_total().pixels == 16);
    CHECK(r.pager_total().misses > 0);  // the pages really travelled
  }
  {
    const dataflow::DataflowResult r = run_dataflow(b, rp, 64, 1);  // and 1-slot queues
    CHECK(max_diff(r.render.color, seq.color) <= 1e-5f);
    check_aovs_equal(r.render, seq);
    CHECK(r.render.stats.rays.total() == seq.stats.rays.total());
    CHECK(r.regions.size() == 64);
  }
}

TEST_CASE("exhausted: a 1x1 image gives the sequential pixel in every mode for 1 to 16 nodes") {
  for (auto [name, size] : {std::pair{"balls", 1}, std::pair{"teapot", 2}}) {
    const testing::BuiltScene b = testing::build_spd(name, size);
    const core::RenderParams rp = tiny(1, 1);
    const core::RenderResult seq = core::render(b.db, b.grid, rp);
    REQUIRE(seq.color.pixels.size() == 3);
    for (std::uint32_t n : {1u, 2u, 16u}) {
      CAPTURE(name);
      CAPTURE(n);
      const control::ReplicatedResult rep = run_replicated(b, rp, n);
      CHECK(same_bytes(rep.render.color, seq.color));
      check_aovs_equal(rep.render, seq);
      const svm::SvmResult sv = run_svm(b, rp, n, n == 1 ? 0 : 1, 256);
      CHECK(same_bytes(sv.render.color, seq.color));
      check_aovs_equal(sv.render, seq);
      const dataflow::DataflowResult df = run_dataflow(b, rp, n, 1);
      CHECK(max_diff(df.render.color, seq.color) <= 1e-5f);
      check_aovs_equal(df.render, seq);
    }
  }
}

TEST_CASE("exhausted: 1-slot mailboxes in replicated and svm mode still give the sequential image") {
  const testing::BuiltScene b = testing::build_spd("teapot", 2);
  const core::RenderParams rp = tiny(16, 12);
  const core::RenderResult seq = core::render(b.db, b.grid, rp);
  for (std::uint32_t n : {2u, 7u, 32u}) {
    CAPTURE(n);
    const control::ReplicatedResult rep = run_replicated(b, rp, n, 1);
    CHECK(same_bytes(rep.render.color, seq.color));
    const svm::SvmResult sv = run_svm(b, rp, n, 1, 128, 1);
    CHECK(same_bytes(sv.render.color, seq.color));
    check_aovs_equal(sv.render, seq);
    CHECK(sv.pager_total().evictions > 0);  // 1-page caches: every other page evicts
  }
}

TEST_CASE("exhausted: dataflow with 1-slot queues and 64 nodes on a reflective scene loses no ray") {
  const testing::BuiltScene b = testing::build_spd("balls", 1);  // mirrors: rays cross many regions
  const core::RenderParams rp = tiny(12, 10);
  const core::RenderResult seq = core::render(b.db, b.grid, rp);
  const dataflow::DataflowResult r = run_dataflow(b, rp, 64, 1);
  CHECK(max_diff(r.render.color, seq.color) <= 1e-5f);
  check_aovs_equal(r.render, seq);
  CHECK(r.render.stats.rays.total() == seq.stats.rays.total());
  CHECK(r.host.spilled > 0);
  CHECK(r.host.forwarded == r.host.spilled);
}

TEST_CASE("exhausted: both mail wake-ups, 1-slot mailboxes included, give the sequential image in every mode") {
  // Replicated and svm default to immediate wake-ups and dataflow to
  // scheduled ones (machine.h): run each the other way. Scheduled mail must
  // not deadlock behind full mailboxes whose owners wait for a permit held by
  // a blocked sender (Scheduler::note_mail's force).
  const testing::BuiltScene b = testing::build_spd("teapot", 2);
  const core::RenderParams rp = tiny(16, 12);
  const core::RenderResult seq = core::render(b.db, b.grid, rp);
  for (std::uint32_t n : {2u, 7u, 32u}) {
    for (std::uint32_t mailbox : {0u, 1u}) {
      CAPTURE(n);
      CAPTURE(mailbox);
      control::ReplicatedParams rep;
      rep.render = rp;
      rep.machine = machine(n, mailbox);
      rep.machine.scheduled_mail = true;
      rep.item_w = rep.item_h = 1;
      const control::ReplicatedResult r = control::render_replicated(b.db, b.grid, rep);
      CHECK(same_bytes(r.render.color, seq.color));
      CHECK(r.run.scheduled_mail);
      CHECK(r.run.service_grants > 0);  // sleeping nodes' mail was served by the scheduler

      svm::SvmParams sp;
      sp.render = rp;
      sp.machine = machine(n, mailbox);
      sp.machine.scheduled_mail = true;
      sp.cache_pages = 2;
      sp.page_size = 128;
      sp.item_w = sp.item_h = 1;
      const svm::SvmResult s = svm::render_svm(b.db, b.grid, sp);
      CHECK(same_bytes(s.render.color, seq.color));
      check_aovs_equal(s.render, seq);
      CHECK(s.run.service_grants > 0);

      dataflow::DataflowParams dp;
      dp.render = rp;
      dp.machine = machine(n, mailbox);
      dp.machine.node_memory = 16 * nodes::kMiB;
      dp.machine.scheduled_mail = false;
      const dataflow::DataflowResult d = dataflow::render_dataflow(b.db, b.grid, dp);
      CHECK(max_diff(d.render.color, seq.color) <= 1e-5f);
      CHECK_FALSE(d.run.scheduled_mail);
      CHECK(d.run.service_grants == 0);
    }
  }
}
