// The host's program in dataflow mode (dataflow.h has the whole protocol):
// it keeps the rays spilled by nodes whose destination was full and
// forwards them when there is room (the paper's optimistic deadlock
// avoidance), detects termination with Mattern's four-counter waves, and
// sums the nodes' contributions into the frame. Internal to the dataflow
// library.
#pragma once

#include <cstdint>
#include <vector>

#include "core/image.h"
#include "core/render.h"
#include "dataflow/dataflow.h"
#include "nodes/node.h"

namespace raynode::dataflow {

/// Where the host puts what the nodes send: the per-pixel sums of colour
/// terms (3 doubles per pixel, row-major, width x height), the AOVs of
/// `render` and the region image that are non-empty, and its counters.
struct HostFrame {
  int width = 0, height = 0;
  std::vector<double>* sums = nullptr;
  core::RenderResult* render = nullptr;
  core::Image* region = nullptr;
  HostFlowStats* stats = nullptr;
};

/// Runs the host's side of a frame over `nodes` nodes until every ray has
/// ended and every contribution is in, then shuts the nodes down. Throws
/// std::logic_error on a protocol fault (a ray for no region, a malformed
/// contribution message, an answer to another wave).
void run_dataflow_host(nodes::NodeContext& host, std::uint32_t nodes, const HostFrame& frame);

}  // namespace raynode::dataflow
