// svm one node against sequential, in one process (docs/results.md, "One
// node, third pass"). Not part of the build; compile against a build tree:
//   g++ -std=c++20 -O3 -DNDEBUG -march=native -ffp-contract=off -I. -o svm1 \
//     docs/results/svm_one_node.cpp build/svm/libraynode_svm.a \
//     build/nodes/libraynode_nodes.a build/core/libraynode_core.a -lfmt -ltbb -lembree3 -lz -lpthread
// Usage: svm1 seq|svm|bench SCENE [tessellate] [pack-cells] [size] [repeats]
//   seq, svm: one render (for callgrind: add -mno-avx512f to the build);
//   bench: alternates sequential (thread CPU time of render_image) and svm
//   --nodes 1 (the node's busy_s), checks the images are equal, prints
//   the medians and minima and their ratios.
// SVM1_DIRECTORY_ORDER=bricked (or linear, the default) sets svm's
// --directory-order.
#include <cstdio>
#include <cstdlib>
#include <string>
#include <ctime>
#include <vector>
#include <algorithm>
#include "core/cell_blocks.h"
#include "core/database.h"
#include "core/direct_view.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/spd.h"
#include "svm/svm.h"
using namespace raynode;
int main(int argc, char** argv) {
  std::string mode = argv[1];
  core::Scene scene = core::make_spd_scene(core::parse_spd_spec(argv[2]));
  int tess = argc > 3 ? std::atoi(argv[3]) : 0;
  if (tess > 0) core::tessellate_scene(scene, tess);
  int pack = argc > 4 ? std::atoi(argv[4]) : 3;
  int size = argc > 5 ? std::atoi(argv[5]) : 256;
  const core::Database db = core::make_database(scene);
  core::Grid grid = core::build_grid(db, core::GridParams{});
  core::RenderParams rp;
  rp.width = rp.height = size;
  double sum = 0;
  // One node holding every page (1 GiB of node memory: no cache misses).
  auto render_svm = [&] {
    svm::SvmParams sp;
    sp.render = rp;
    sp.machine.nodes = 1;
    sp.machine.node_memory = std::size_t(1) << 30;
    sp.pack_min = pack;
    if (const char* o = std::getenv("SVM1_DIRECTORY_ORDER")) sp.directory_order = svm::parse_directory_order(o);
    return svm::render_svm(db, grid, sp);
  };
  auto cpu = [] { timespec t; clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t); return t.tv_sec + 1e-9 * t.tv_nsec; };
  if (mode == "bench") {
    int reps = argc > 6 ? std::atoi(argv[6]) : 7;
    core::CellBlocks blocks = core::build_cell_blocks(db, grid, 3);
    core::DirectView view(db, grid, &blocks);
    std::vector<double> a, b;
    for (int i = 0; i < reps; ++i) {
      double t0 = cpu();
      core::RenderResult r = core::render_image(view, db, rp);
      a.push_back(cpu() - t0);
      svm::SvmResult s = render_svm();
      b.push_back(s.run.nodes[0].counters.busy_s);
      if (s.render.color.pixels != r.color.pixels) { std::printf("IMAGES DIFFER\n"); return 1; }
    }
    std::sort(a.begin(), a.end()); std::sort(b.begin(), b.end());
    std::printf("seq %.4f  svm %.4f  ratio %.3f   (min: %.4f %.4f %.3f)\n", a[reps/2], b[reps/2], b[reps/2]/a[reps/2], a[0], b[0], b[0]/a[0]);
    return 0;
  }
  if (mode == "seq") {
    core::CellBlocks blocks = core::build_cell_blocks(db, grid, 3);
    core::DirectView view(db, grid, &blocks);
    core::RenderResult r = core::render_image(view, db, rp);
    for (float v : r.color.pixels) sum += v;
  } else {
    svm::SvmResult r = render_svm();
    for (float v : r.render.color.pixels) sum += v;
  }
  std::printf("%s sum %.6f\n", mode.c_str(), sum);
}
