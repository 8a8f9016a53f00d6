#include "modes/modes.h"

#include <fmt/core.h>

#include <stdexcept>
#include <utility>

#include "core/direct_view.h"
#include "core/embree_view.h"

namespace raynode::modes {

Mode parse_mode(std::string_view name) {
  if (name == "sequential") return Mode::kSequential;
  if (name == "shared") return Mode::kShared;
  if (name == "replicated") return Mode::kReplicated;
  if (name == "svm") return Mode::kSvm;
  if (name == "dataflow") return Mode::kDataflow;
  throw std::invalid_argument(
      fmt::format("unknown mode '{}' (expected sequential, shared, replicated, svm or dataflow)", name));
}

const char* mode_name(Mode mode) {
  switch (mode) {
    case Mode::kSequential: return "sequential";
    case Mode::kShared: return "shared";
    case Mode::kReplicated: return "replicated";
    case Mode::kSvm: return "svm";
    case Mode::kDataflow: return "dataflow";
  }
  return "?";
}

const nodes::RunReport* RunResult::run() const {
  if (replicated) return &replicated->run;
  if (svm) return &svm->run;
  if (dataflow) return &dataflow->run;
  return nullptr;
}

const std::vector<control::WorkStats>* RunResult::work() const {
  if (replicated) return &replicated->work;
  if (svm) return &svm->work;
  return nullptr;
}

const std::vector<core::RenderStats>* RunResult::tracing() const {
  if (replicated) return &replicated->tracing;
  if (svm) return &svm->tracing;
  return nullptr;
}

namespace {

/// Refuses the requests no mode can honour.
void check_request(const RunRequest& req) {
  const char* mode = mode_name(req.mode);
  if (is_node_mode(req.mode) && req.embree)
    throw std::invalid_argument(fmt::format("{} mode traces with the grid, not with Embree", mode));
  if (req.node_aov && !is_node_mode(req.mode))
    throw std::invalid_argument(fmt::format("the node AOV needs a node mode, not {} mode", mode));
  if (req.pages_aov && req.mode != Mode::kSvm)
    throw std::invalid_argument(fmt::format("the pages AOV needs svm mode, not {} mode", mode));
  if (req.region_aov && req.mode != Mode::kDataflow)
    throw std::invalid_argument(fmt::format("the region AOV needs dataflow mode, not {} mode", mode));
  if (!is_node_mode(req.mode) && req.nodes.machine.nodes > 1)
    throw std::invalid_argument(
        fmt::format("{} nodes need a node mode; {} mode runs in this process", req.nodes.machine.nodes, mode));
}

RunResult render_in_process(const core::Database& db, const core::Grid* grid, const RunRequest& req) {
  core::RenderParams params = req.render;
  params.mode = req.mode == Mode::kShared ? core::RenderMode::kShared : core::RenderMode::kSequential;
  RunResult out;
  out.render = req.embree ? core::render_image(core::EmbreeView(db, *req.embree), db, params)
                          : core::render_image(core::DirectView(db, *grid, req.blocks), db, params);
  return out;
}

RunResult render_replicated(const core::Database& db, const core::Grid& grid, const RunRequest& req) {
  const NodeModeParams& n = req.nodes;
  control::ReplicatedParams p;
  p.render = req.render;
  p.machine = n.machine;
  p.item_w = n.item_w, p.item_h = n.item_h;
  p.submaps = n.submaps;
  p.node_aov = req.node_aov;
  RunResult out;
  out.replicated = control::render_replicated(db, grid, p);
  out.render = std::move(out.replicated->render);
  out.node = std::move(out.replicated->node);
  return out;
}

RunResult render_svm(const core::Database& db, const core::Grid& grid, const RunRequest& req) {
  const NodeModeParams& n = req.nodes;
  svm::SvmParams p;
  p.render = req.render;
  p.machine = n.machine;
  p.item_w = n.item_w, p.item_h = n.item_h;
  p.submaps = n.submaps;
  p.page_size = n.page_size;
  p.directory_order = n.directory_order;
  p.primitive_order = n.primitive_order;
  p.fetch_by_get = n.fetch_by_get;
  p.cache_pages = n.cache_pages;
  p.cache_fraction = n.cache_fraction;
  p.pack_min = n.pack_min;
  p.node_aov = req.node_aov;
  p.pages_aov = req.pages_aov;
  RunResult out;
  out.svm = svm::render_svm(db, grid, p);
  out.render = std::move(out.svm->render);
  out.node = std::move(out.svm->node);
  out.pages = std::move(out.svm->pages);
  return out;
}

RunResult render_dataflow(const core::Database& db, const core::Grid& grid, const RunRequest& req) {
  const NodeModeParams& n = req.nodes;
  dataflow::DataflowParams p;
  p.render = req.render;
  p.machine = n.machine;
  p.machine.mailbox_capacity = n.queue_capacity;
  p.send_queue_slots = n.send_queue;
  p.subsample = n.subsample;
  p.partition = n.partition;
  p.region_aov = req.region_aov || req.node_aov;
  p.grid.kind = grid.kind();  // each region's local grid is of the host grid's kind
  RunResult out;
  out.dataflow = dataflow::render_dataflow(db, grid, p);
  out.render = std::move(out.dataflow->render);
  if (req.node_aov) out.node = out.dataflow->region;  // region i belongs to node i
  if (req.region_aov) out.region = std::move(out.dataflow->region);
  return out;
}

}  // namespace

RunResult render(const core::Database& db, const core::Grid* grid, const RunRequest& req) {
  check_request(req);
  if (!grid && !req.embree) throw std::invalid_argument(fmt::format("{} mode needs the grid", mode_name(req.mode)));
  RunResult out;
  switch (req.mode) {
    case Mode::kSequential:
    case Mode::kShared: return render_in_process(db, grid, req);
    case Mode::kReplicated: out = render_replicated(db, *grid, req); break;
    case Mode::kSvm: out = render_svm(db, *grid, req); break;
    case Mode::kDataflow: out = render_dataflow(db, *grid, req); break;
  }
  // The node modes' progress counts what the host received; the frame is whole now.
  if (req.render.progress)
    req.render.progress->store(std::uint64_t(out.render.color.width) * std::uint64_t(out.render.color.height));
  return out;
}

}  // namespace raynode::modes
