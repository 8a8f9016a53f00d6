// Determinism: one scene gives the same image across repeated runs, node
// counts and modes. Work stealing, page faults, spills and thread scheduling
// differ from run to run (and more so with a network model and with the OS
// scheduling the node threads), so equality here means the images do not
// depend on who computed what. Sequential, shared, replicated and svm agree
// byte for byte; dataflow agrees within 1e-5 per channel (it adds the
// contributions of a pixel in their order of arrival) and exactly in its AOVs.
#include <doctest/doctest.h>

#include <cstdint>
#include <vector>

#include "core/render.h"
#include "dataflow/dataflow.h"
#include "nodes/network.h"
#include "control/replicated.h"
#include "robustness/compare.h"
#include "svm/svm.h"
#include "test_scenes.h"

using namespace raynode;
using robustness::max_diff;
using testing::same_bytes;

namespace {

/// Machine settings that vary the schedule: none, the iPSC/2 network model,
/// and the OS scheduling the node threads (no virtual-time scheduler).
enum class Schedule { kDefault, kNetwork, kOsThreads };

nodes::MachineParams machine(std::uint32_t nodes, Schedule s) {
  nodes::MachineParams m;
  m.nodes = nodes;
  m.node_memory = 16 * nodes::kMiB;
  m.timeout_s = 120;
  if (s == Schedule::kNetwork) m.network = nodes::make_network("ipsc2", 1e-4);
  if (s == Schedule::kOsThreads) m.schedule_window_s = -1;
  return m;
}

}  // namespace

TEST_CASE("determinism: sequential, shared, replicated and svm images are byte-identical across runs and node counts") {
  for (auto [name, size, tess] : {std::tuple{"rings", 1, 0}, std::tuple{"mount", 2, 1}}) {
    const testing::BuiltScene b = testing::build_spd(name, size, tess);
    core::RenderParams rp;
    rp.width = 36;
    rp.height = 28;
    rp.depth_aov = rp.primitive_aov = true;
    const core::RenderResult seq = core::render(b.db, b.grid, rp);
    for (int run = 0; run < 2; ++run) {
      CAPTURE(name);
      CAPTURE(run);
      CHECK(same_bytes(core::render(b.db, b.grid, rp).color, seq.color));
#if !defined(__SANITIZE_THREAD__)
      // Shared mode runs on TBB, which ThreadSanitizer cannot see into (false
      // reports inside the uninstrumented libtbb): checked in the other builds.
      core::RenderParams shared = rp;
      shared.mode = core::RenderMode::kShared;
      shared.tile_size = 4;  // many tiles: threads interleave
      CHECK(same_bytes(core::render(b.db, b.grid, shared).color, seq.color));
#endif
      for (std::uint32_t n : {1u, 3u, 8u, 32u})
        for (Schedule s : {Schedule::kDefault, Schedule::kNetwork, Schedule::kOsThreads}) {
          CAPTURE(n);
          CAPTURE(int(s));
          control::ReplicatedParams p;
          p.render = rp;
          p.machine = machine(n, s);
          const control::ReplicatedResult r = control::render_replicated(b.db, b.grid, p);
          CHECK(same_bytes(r.render.color, seq.color));
          CHECK(same_bytes(r.render.depth, seq.depth));
          CHECK(same_bytes(r.render.primitive, seq.primitive));
        }
      for (std::uint32_t n : {2u, 5u, 16u})
        for (std::uint32_t cache : {1u, 0u})
          for (Schedule s : {Schedule::kNetwork, Schedule::kOsThreads}) {
            CAPTURE(n);
            CAPTURE(cache);
            CAPTURE(int(s));
            svm::SvmParams p;
            p.render = rp;
            p.machine = machine(n, s);
            p.page_size = 256;
            p.cache_pages = cache;
            const svm::SvmResult r = svm::render_svm(b.db, b.grid, p);
            CHECK(same_bytes(r.render.color, seq.color));
            CHECK(same_bytes(r.render.depth, seq.depth));
            CHECK(same_bytes(r.render.primitive, seq.primitive));
          }
    }
  }
}

TEST_CASE("determinism: dataflow images stay within 1e-5 of sequential and of each other across runs and node counts") {
  const testing::BuiltScene b = testing::build_spd("balls", 1);  // reflective: rays cross regions
  core::RenderParams rp;
  rp.width = 32;
  rp.height = 24;
  rp.depth_aov = rp.normal_aov = rp.primitive_aov = true;
  const core::RenderResult seq = core::render(b.db, b.grid, rp);
  std::vector<core::Image> images;
  for (int run = 0; run < 2; ++run)
    for (std::uint32_t n : {2u, 6u, 24u})
      for (Schedule s : {Schedule::kDefault, Schedule::kOsThreads}) {
        CAPTURE(run);
        CAPTURE(n);
        CAPTURE(int(s));
        dataflow::DataflowParams p;
        p.render = rp;
        p.machine = machine(n, s);
        p.machine.mailbox_capacity = run == 0 ? 0 : 2;  // the second run also spills
        p.send_queue_slots = run == 0 ? 0 : 2;
        const dataflow::DataflowResult r = dataflow::render_dataflow(b.db, b.grid, p);
        CHECK(max_diff(r.render.color, seq.color) <= 1e-5f);
        CHECK(same_bytes(r.render.depth, seq.depth));
        CHECK(same_bytes(r.render.normal, seq.normal));
        CHECK(same_bytes(r.render.primitive, seq.primitive));
        CHECK(r.render.stats.rays.total() == seq.stats.rays.total());
        images.push_back(r.render.color);
      }
  for (const core::Image& a : images)
    for (const core::Image& c : images) CHECK(max_diff(a, c) <= 2e-5f);
}
