// raynode: entry point. Parses the command line (CLI11), runs the chosen
// subcommand, and maps errors to one clear line on stderr and an exit code
// (see commands.h).
#include <fmt/core.h>

#include <cstdio>
#include <exception>

#include "apps/commands.h"
#include "core/cell_blocks.h"
#include "core/nff.h"

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

int main(int argc, char** argv) {
  using namespace raynode;
  CLI::App app{"raynode: the parallel ray tracers of Badouel, Bouatouch and Priol (IEEE CG&A 1994) on an "
               "emulated distributed-memory machine"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "raynode 0.1.0");
  apps::register_scene_commands(app);
  apps::register_validate_command(app);
  apps::register_bench_command(app);
  apps::register_bench_nodes_commands(app);
  apps::register_render_command(app);
  apps::register_sweep_commands(app);
  apps::register_bench_quality_command(app);
  apps::register_bench_cost_model_command(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    fmt::print(stderr, "raynode: error: {}\nRun 'raynode --help' (or 'raynode COMMAND --help') for usage.\n",
               e.what());
    return 2;
  } catch (const core::ParseError& e) {
    fmt::print(stderr, "{}\n", e.what());
    return 1;
  } catch (const apps::UsageError& e) {
    fmt::print(stderr, "raynode: error: {}\n", e.what());
    return 2;
  } catch (const std::invalid_argument& e) {
    fmt::print(stderr, "raynode: error: {}\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    fmt::print(stderr, "raynode: error: {}\n", e.what());
    return 1;
  }
  return 0;
}
