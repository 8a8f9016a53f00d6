// The options several subcommands share (commands.h): the scene, the grid
// walk's empty-space jumps, packed cells.
#include <fmt/core.h>

#include "apps/commands.h"
#include "core/cell_blocks.h"

namespace raynode::apps {

void add_scene_options(CLI::App& cmd, core::SceneSource& source) {
  cmd.add_option("scene", source.spec,
                 "NFF file (.nff, .nff.gz) or built-in SPD scene name[:size]: teapot, mount, rings, tetra, balls "
                 "(e.g. teapot:8, mount:6, tetra:9)")
      ->required();
  cmd.add_option("--tessellate,-t", source.tessellate,
                 "Replace spheres by 12*R^2 and cones by 8*R triangles, as SPD's -t R (0 = curved)")
      ->check(CLI::Range(0, 1000));
}

void add_skip_empty_option(CLI::App& cmd, bool& skip_empty) {
  cmd.add_option_function<std::string>(
         "--skip-empty", [&skip_empty](const std::string& v) { skip_empty = v == "on"; },
         "Grid walk: on = jump over empty space (Chebyshev distances kept in empty cells); off = step cell by "
         "cell, as the paper's tracer (same hits, more cells visited) [default: on]")
      ->check(CLI::IsMember({"on", "off"}));
}

void add_pack_cells_option(CLI::App& cmd, std::uint32_t& pack_min) {
  cmd.add_option_function<std::string>(
         "--pack-cells",
         [&pack_min](const std::string& v) { pack_min = v == "off" ? 0 : std::uint32_t(std::stoul(v)); },
         fmt::format("Grid tracing: cells listing at least N triangles keep them in SIMD blocks of {} and are "
                     "tested a block at a time (same hits); off = every cell walks its primitive list, as the "
                     "paper's tracer [default: {} in sequential and shared modes, bench and validate; off in svm, "
                     "which then pages the blocks (pages of 512 B or more); replicated and dataflow: off only]",
                     raynode::core::kBlockLanes, raynode::core::kDefaultPackMin))
      ->check(CLI::IsMember({"off"}) | CLI::Range(1, 1 << 20));
}

}  // namespace raynode::apps
