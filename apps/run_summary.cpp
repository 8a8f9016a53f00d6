#include "apps/run_summary.h"

#include <fmt/core.h>

#include <nlohmann/json.hpp>

#include "nodes/arena.h"

namespace raynode::apps {

namespace {

/// The value at `key` of `j` if it is a number, else nullptr.
const nlohmann::json* number(const nlohmann::json& j, const char* key) {
  if (!j.is_object()) return nullptr;
  const auto it = j.find(key);
  return it != j.end() && it->is_number() ? &*it : nullptr;
}

/// The value at `key` of `j` if it is a string, else nullptr.
const std::string* text(const nlohmann::json& j, const char* key) {
  if (!j.is_object()) return nullptr;
  const auto it = j.find(key);
  return it != j.end() && it->is_string() ? it->get_ptr<const std::string*>() : nullptr;
}

/// Seconds in the unit that reads best: "412 us", "5.19 ms", "1.234 s".
std::string seconds(double s) {
  if (s < 1e-3) return fmt::format("{:.0f} us", s * 1e6);
  if (s < 1) return fmt::format("{:.2f} ms", s * 1e3);
  return fmt::format("{:.3f} s", s);
}

/// Appends ", TEXT" (or TEXT to an empty line).
void add(std::string& line, const std::string& text) {
  if (!line.empty()) line += ", ";
  line += text;
}

std::string machine_line(const nlohmann::json& m) {
  std::string line = fmt::format("machine: {} nodes", m.value("count", 0));
  std::string how;
  if (const auto* topology = text(m, "topology")) add(how, *topology);
  if (const auto* net = text(m, "network")) add(how, *net == "none" ? "no network costs" : *net + " network");
  if (const auto* clock = text(m, "clock")) add(how, *clock + " clock");
  if (const auto* transport = text(m, "transport")) add(how, "on " + *transport + " ranks");
  if (!how.empty()) line += " (" + how + ")";
  std::string parts;
  if (const auto* tp = number(m, "parallel_time_s")) add(parts, "T_p " + seconds(tp->get<double>()));
  if (m.contains("transport"))
    if (const auto* wall = number(m, "wall_s")) add(parts, "wall " + seconds(wall->get<double>()));
  if (const auto* e = number(m, "efficiency_estimate"))
    add(parts, fmt::format("efficiency {:.1f}% (summed busy time / (N x T_p))", 100 * e->get<double>()));
  if (m.contains("total")) {
    const nlohmann::json& t = m["total"];  // number() checks that it is an object
    if (const auto* n = number(t, "messages_sent")) {
      std::string msgs = fmt::format("{} messages", n->get<std::uint64_t>());
      if (const auto* b = number(t, "bytes_sent")) msgs += " (" + nodes::format_bytes(b->get<std::size_t>()) + ")";
      add(parts, msgs);
    }
  }
  return parts.empty() ? line : line + ": " + parts;
}

std::string work_line(const nlohmann::json& m) {
  const nlohmann::json& w = m["work"];
  std::string line;
  if (m.contains("submaps"))
    if (const auto* rule = text(m["submaps"], "rule")) add(line, *rule + " submaps");
  const auto* grants = text(m, "work_grants");
  const auto* requests = text(m, "work_requests");
  if (requests && *requests == "off") {  // no request, no grant: nothing to count
    add(line, "work requests off (static submaps only)");
    return "work: " + line;
  }
  if (const auto* g = number(w, "grants")) {
    std::string granted = fmt::format("{} work items granted", g->get<std::uint64_t>());
    if (const auto* p = number(w, "pixels_granted")) granted += fmt::format(" ({} pixels)", p->get<std::uint64_t>());
    add(line, granted);
  }
  if (const auto* r = number(w, "requests_sent")) add(line, fmt::format("{} work requests", r->get<std::uint64_t>()));
  if (grants && requests) add(line, fmt::format("{} grants, {} requests", *grants, *requests));
  return "work: " + line;
}

std::string svm_line(const nlohmann::json& s) {
  std::string line;
  if (const auto* pages = number(s, "pages_total")) {
    std::string db = fmt::format("{} pages", pages->get<std::uint64_t>());
    if (const auto* ps = number(s, "page_size")) db += fmt::format(" of {} B", ps->get<std::uint64_t>());
    if (const auto* b = number(s, "database_bytes"))
      db += " (database " + nodes::format_bytes(b->get<std::size_t>()) + ")";
    add(line, db);
  }
  if (const auto* ppp = number(s, "pages_per_pixel")) add(line, fmt::format("{:.2f} pages per pixel", ppp->get<double>()));
  if (const auto* f = number(s, "misses")) {
    std::string faults = fmt::format("{} page faults", f->get<std::uint64_t>());
    if (const auto* r = number(s, "miss_ratio")) faults += fmt::format(" (miss ratio {:.3f}%)", 100 * r->get<double>());
    add(line, faults);
  }
  if (const auto* e = number(s, "evictions")) add(line, fmt::format("{} evictions", e->get<std::uint64_t>()));
  if (const auto* b = number(s, "page_bytes_received"))
    add(line, nodes::format_bytes(b->get<std::size_t>()) + " of pages received");
  return "svm: " + line;
}

std::string dataflow_line(const nlohmann::json& d) {
  std::string line;
  if (const auto* r = number(d, "regions")) {
    std::string regions = fmt::format("{} regions", r->get<std::uint64_t>());
    if (const auto* partition = text(d, "partition")) regions += " (" + *partition + " partition)";
    add(line, regions);
  }
  if (const auto* n = number(d, "ray_messages_total")) add(line, fmt::format("{} ray messages", n->get<std::uint64_t>()));
  if (const auto* n = number(d, "ray_segments"))
    add(line, fmt::format("{} ray segments traced", n->get<std::uint64_t>()));
  if (const auto* b = number(d, "balance")) add(line, fmt::format("balance {:.2f} (mean / max busy time)", b->get<double>()));
  return "dataflow: " + line;
}

}  // namespace

std::vector<std::string> node_run_summary(const nlohmann::json& machine, const nlohmann::json& svm,
                                          const nlohmann::json& dataflow) {
  std::vector<std::string> lines;
  if (!machine.is_object()) return lines;
  lines.push_back(machine_line(machine));
  if (machine.contains("work") && machine["work"].is_object()) lines.push_back(work_line(machine));
  if (svm.is_object()) lines.push_back(svm_line(svm));
  if (dataflow.is_object()) lines.push_back(dataflow_line(dataflow));
  return lines;
}

}  // namespace raynode::apps
