#include "apps/render_stats.h"

#include "apps/commands.h"
#include "apps/run_info.h"

namespace raynode::apps {

namespace {

/// The machine report's keys that every node mode fills the same way.
void fill_work_stats(const std::vector<control::WorkStats>& work, const std::vector<core::RenderStats>& tracing,
                     const nodes::RunReport& run, int node_count, nlohmann::json& j) {
  control::WorkStats sum;
  for (const control::WorkStats& w : work) sum += w;
  double busy = 0;
  for (const nodes::NodeReport& n : run.nodes) busy += n.counters.busy_s;
  j["work_s"] = busy;
  // Without a one-node run, T_1 is estimated by the summed busy time.
  j["efficiency_estimate"] = run.parallel_time_s > 0 ? busy / (double(node_count) * run.parallel_time_s) : 0.0;
  j["work"] = {{"items_own", sum.items_own},         {"items_received", sum.items_received},
               {"requests_sent", sum.requests_sent}, {"requests_forwarded", sum.requests_forwarded},
               {"grants", sum.grants_given},         {"pixels_granted", sum.pixels_granted},
               {"request_hops", sum.request_hops}};
  for (std::size_t i = 0; i < work.size() && i < j["per_node"].size(); ++i) {
    auto& e = j["per_node"][i];
    e["pixels"] = work[i].pixels;
    e["grants_given"] = work[i].grants_given;
    e["items_received"] = work[i].items_received;
    e["rays"] = tracing[i].rays.total();
  }
}

}  // namespace

void node_mode_json(const modes::RunResult& r, int nodes, FrameExtras& extras) {
  const nodes::RunReport* run = r.run();
  if (!run) return;
  extras.nodes = run->to_json(true);
  if (r.replicated) {
    extras.nodes["submaps"] = r.replicated->submaps.to_json();
    extras.nodes["database_bytes_per_node"] = r.replicated->database_bytes;
  }
  if (r.svm) {
    extras.nodes["submaps"] = r.svm->submaps.to_json();
    extras.svm = r.svm->to_json();
  }
  if (r.work()) {
    fill_work_stats(*r.work(), *r.tracing(), *run, nodes, extras.nodes);
  } else {
    double busy = 0;
    for (const nodes::NodeReport& n : run->nodes) busy += n.counters.busy_s;
    extras.nodes["work_s"] = busy;
    extras.nodes["efficiency_estimate"] =
        run->parallel_time_s > 0 ? busy / (double(nodes) * run->parallel_time_s) : 0.0;
  }
  if (r.dataflow) extras.dataflow = r.dataflow->to_json();
}

nlohmann::json render_stats_json(const RenderRecord& r) {
  const core::RenderStats& s = r.result.stats;
  const core::SceneCounts sc = r.scene.counts();
  const core::DatabaseCounts dc = r.db.counts();
  nlohmann::json j = {
      {"scene", r.scene_spec},
      {"tessellate", r.tessellate},
      {"floor", r.floor},
      {"mode", r.mode},
      {"accel", r.accel},
      {"nodes", r.nodes},
      {"width", r.result.color.width},
      {"height", r.result.color.height},
      {"spp", r.params.spp},
      {"max_depth", r.params.max_depth},
      {"min_weight", r.params.min_weight},
      {"shadow_rays", core::shadow_rays_name(r.params.shadow_rays)},
      {"rays",
       {{"primary", s.rays.primary},
        {"shadow", s.rays.shadow},
        {"reflected", s.rays.reflected},
        {"refracted", s.rays.refracted},
        {"refracted_tir", s.rays.refracted_tir},
        {"total", s.rays.total()}}},
      {"skipped",
       {{"reflection_ks0", s.skipped.reflection_ks0},
        {"refraction_t0", s.skipped.refraction_t0},
        {"shadow_backfacing", s.skipped.shadow_backfacing},
        {"highlight_marker", s.skipped.highlight_marker},
        {"depth_limit", s.skipped.depth_limit},
        {"min_weight", s.skipped.min_weight}}},
      {"tests",
       {{"triangle", s.traversal.triangle_tests},
        {"sphere", s.traversal.sphere_tests},
        {"cone", s.traversal.cone_tests}}},
      {"cells_visited", s.traversal.cells_visited},
      {"empty_jumps", s.traversal.empty_jumps},
      {"mailbox_skips", s.traversal.mailbox_skips},
      {"time", {{"wall_s", r.wall_s}, {"cpu_s", r.cpu_s}, {"accel_build_s", r.build_s}}},
      {"scene_counts",
       {{"polygons", sc.polygons},
        {"patches", sc.patches},
        {"spheres", sc.spheres},
        {"cones", sc.cones},
        {"lights", sc.lights},
        {"materials", sc.materials}}},
      {"database",
       {{"primitives", r.db.primitives.size()},
        {"triangles", dc.triangles},
        {"spheres", dc.spheres},
        {"cones", dc.cones}}},
      {"output", r.output},
      {"run", run_json()},
  };
  if (r.grid) {
    j["grid_resolution"] = {r.grid->info.res[0], r.grid->info.res[1], r.grid->info.res[2]};
    j["grid"] = grid_json(*r.grid);
    j["grid"]["build_s"] = r.build_s;
    j["skip_empty"] = r.skip_empty;
    // svm packs its paged database, not the host's grid.
    const bool svm = !r.extras.svm.is_null();
    j["pack_cells"] = svm ? r.extras.svm.at("pack_cells") : nlohmann::json(r.blocks ? r.blocks->min_triangles : 0);
    j["packed_blocks"] = svm ? r.extras.svm.at("packed_blocks")
                             : nlohmann::json(r.blocks ? r.blocks->blocks.size() : 0);
    j["packed_sphere_blocks"] = r.blocks ? r.blocks->sphere_blocks.size() : 0;  // svm packs triangles only
  }
  for (const auto& [name, path] : r.aov_files) j["aov_outputs"][name] = path;
  if (!r.extras.nodes.is_null()) {
    // "nodes" stays the count; the machine's totals and each node's counters beside it.
    j["per_node"] = r.extras.nodes.at("per_node");
    j["machine"] = r.extras.nodes;
    j["machine"].erase("per_node");
  }
  if (!r.extras.svm.is_null()) {
    j["svm"] = r.extras.svm;
    j["svm"]["per_node"] = nullptr;
    j["svm"].erase("per_node");
    for (std::size_t i = 0; i < r.extras.svm.at("per_node").size() && i < j["per_node"].size(); ++i)
      j["per_node"][i]["svm"] = r.extras.svm.at("per_node")[i];
  }
  if (!r.extras.dataflow.is_null()) j["dataflow"] = r.extras.dataflow;
  return j;
}

}  // namespace raynode::apps
