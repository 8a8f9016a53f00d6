// raynode: entry point. Parses the command line (CLI11), runs the chosen
// subcommand, and maps errors to one clear line on stderr and an exit code
// (see commands.h).
#include <fmt/core.h>

#include <cstdio>
#include <exception>
#include <new>

#include "apps/commands.h"
#include "apps/output_files.h"
#include "apps/watchdog.h"
#include "core/nff.h"

int main(int argc, char** argv) {
  using namespace raynode;
  apps::mark_process_start();  // --timeout counts from here
  apps::install_cleanup_handlers();
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
  } catch (const apps::Interrupted& e) {
    fmt::print(stderr, "raynode: {}\n", e.what());
    return 130;
  } catch (const apps::UsageError& e) {
    fmt::print(stderr, "raynode: error: {}\n", e.what());
    return 2;
  } catch (const std::invalid_argument& e) {
    fmt::print(stderr, "raynode: error: {}\n", e.what());
    return 2;
  } catch (const std::bad_alloc&) {
    fmt::print(stderr, "raynode: error: out of memory (std::bad_alloc): the scene, its grid, the image, or in the "
                       "node modes the nodes' memories and mailboxes (--nodes x --node-memory, --queue-capacity) need "
                       "more than this process could get; try a smaller scene, -t, image or fewer nodes\n");
    return 1;
  } catch (const std::exception& e) {
    fmt::print(stderr, "raynode: error: {}\n", e.what());
    return 1;
  }
  return 0;
}
