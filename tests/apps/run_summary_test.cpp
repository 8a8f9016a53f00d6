// apps/run_summary.h: the lines `raynode render` prints after a node-mode run.
#include "apps/run_summary.h"

#include <doctest/doctest.h>
#include <fmt/core.h>

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "svm/svm.h"
#include "test_scenes.h"

using raynode::apps::node_run_summary;
using nlohmann::json;

namespace {

/// The one line that starts with `prefix`; fails the test when there is not exactly one.
std::string line_of(const std::vector<std::string>& lines, const std::string& prefix) {
  std::string found;
  int n = 0;
  for (const std::string& l : lines)
    if (l.rfind(prefix, 0) == 0) {
      found = l;
      ++n;
    }
  CHECK_MESSAGE(n == 1, "lines starting with '", prefix, "': ", n);
  return found;
}

bool has(const std::string& line, const std::string& part) {
  const bool ok = line.find(part) != std::string::npos;
  if (!ok) MESSAGE("'", part, "' not in '", line, "'");
  return ok;
}

}  // namespace

TEST_CASE("run summary: an in-process mode (no machine object) prints no summary line") {
  CHECK(node_run_summary(json(), json(), json()).empty());
}

TEST_CASE("run summary: the machine and work lines carry the report's figures") {
  const json machine = {{"count", 16},
                        {"topology", "hypercube"},
                        {"network", "ipsc2"},
                        {"clock", "model"},
                        {"parallel_time_s", 0.0051855},
                        {"efficiency_estimate", 0.93535},
                        {"total", {{"messages_sent", 3908}, {"bytes_sent", 3 * 1024 * 1024}}},
                        {"submaps", {{"rule", "balanced"}}},
                        {"work_grants", "nearest"},
                        {"work_requests", "last-grantor"},
                        {"work", {{"grants", 335}, {"pixels_granted", 2692}, {"requests_sent", 351}}}};
  const std::vector<std::string> lines = node_run_summary(machine, json(), json());
  REQUIRE(lines.size() == 2);
  const std::string m = line_of(lines, "machine: 16 nodes (hypercube, ipsc2 network, model clock)");
  CHECK(has(m, "T_p 5.19 ms"));
  CHECK(has(m, "efficiency 93.5%"));
  CHECK(has(m, "3908 messages (3 MiB)"));
  const std::string w = line_of(lines, "work: ");
  CHECK(has(w, "balanced submaps"));
  CHECK(has(w, "335 work items granted (2692 pixels)"));
  CHECK(has(w, "351 work requests"));
  CHECK(has(w, "nearest grants, last-grantor requests"));
}

TEST_CASE("run summary: work requests off read as static submaps, not as a route") {
  const json machine = {{"count", 4},
                        {"submaps", {{"rule", "square"}}},
                        {"work_grants", "item"},
                        {"work_requests", "off"},
                        {"work", {{"grants", 0}, {"requests_sent", 0}}}};
  const std::string w = line_of(node_run_summary(machine, json(), json()), "work: ");
  CHECK(w == "work: square submaps, work requests off (static submaps only)");  // no route, and no counts that are 0 by design
}

TEST_CASE("run summary: times read in us, ms or s, and a missing key is left out, not invented") {
  auto machine_line = [](double tp) {
    return node_run_summary(json{{"count", 2}, {"parallel_time_s", tp}}, json(), json()).at(0);
  };
  CHECK(machine_line(412e-6) == "machine: 2 nodes: T_p 412 us");
  CHECK(machine_line(1.2345) == "machine: 2 nodes: T_p 1.234 s");
  CHECK(node_run_summary(json{{"count", 3}}, json(), json()) == std::vector<std::string>{"machine: 3 nodes"});
  CHECK(node_run_summary(json{{"count", 3}, {"network", "none"}}, json(), json()).at(0) ==
        "machine: 3 nodes (no network costs)");
  // A non-number where a number belongs is skipped too.
  CHECK(node_run_summary(json{{"count", 3}, {"parallel_time_s", "soon"}}, json(), json()).at(0) == "machine: 3 nodes");
}

TEST_CASE("run summary: the dataflow line names regions, ray messages and balance") {
  const json df = {{"regions", 8}, {"partition", "balanced"}, {"ray_messages_total", 2587},
                   {"ray_segments", 15246}, {"balance", 0.742}};
  const std::string d = line_of(node_run_summary(json{{"count", 8}}, json(), df), "dataflow: ");
  CHECK(has(d, "8 regions (balanced partition)"));
  CHECK(has(d, "2587 ray messages"));
  CHECK(has(d, "15246 ray segments traced"));
  CHECK(has(d, "balance 0.74"));
}

TEST_CASE("run summary: the svm line reports a real run's pages, pages per pixel and faults") {
  using namespace raynode;
  const testing::BuiltScene b = testing::build_spd("tetra", 3);
  svm::SvmParams p;
  p.render.width = p.render.height = 24;
  p.machine.nodes = 4;
  p.machine.node_memory = 4 * nodes::kMiB;
  p.machine.timeout_s = 120;
  p.page_size = 256;
  p.cache_pages = 2;  // evictions too
  const svm::SvmResult r = svm::render_svm(b.db, b.grid, p);
  const svm::PagerStats t = r.pager_total();
  REQUIRE(t.misses > 0);
  REQUIRE(t.evictions > 0);
  const std::vector<std::string> lines = node_run_summary(r.run.to_json(true), r.to_json(), json());
  line_of(lines, "machine: 4 nodes");
  const std::string s = line_of(lines, "svm: ");
  CHECK(has(s, fmt::format("{} pages of 256 B (database {})", r.layout.pages,
                           nodes::format_bytes(r.layout.object_bytes))));
  CHECK(has(s, fmt::format("{:.2f} pages per pixel", t.pages_per_pixel())));
  CHECK(has(s, fmt::format("{} page faults (miss ratio {:.3f}%)", t.misses, 100 * t.miss_ratio())));
  CHECK(has(s, fmt::format("{} evictions", t.evictions)));
}
