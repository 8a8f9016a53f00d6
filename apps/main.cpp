// raynode: entry point. Parses the command line (CLI11), runs the chosen
// subcommand, and maps errors to one clear line on stderr and an exit code
// (see commands.h).
#include <fmt/core.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>
#include <cstdio>
#include <exception>
#include <new>
#include <optional>
#include <string>
#include <vector>

#include "apps/commands.h"
#include "apps/transports.h"
#include "apps/help_format.h"
#include "apps/output_files.h"
#include "apps/run_info.h"
#include "apps/watchdog.h"
#include "core/nff.h"

namespace {

/// Edit distance (insertions, deletions, substitutions) between a and b.
std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] != b[j - 1])});
      diagonal = up;
    }
  }
  return row[b.size()];
}

/// For a command line whose command word is not a command (`raynode rendr`,
/// `raynode bench acel`; CLI11 says only "A subcommand is required"): the
/// error line naming it, the commands there are, and the nearest one.
std::optional<std::string> unknown_command(CLI::App& app, int argc, char** argv) {
  CLI::App* at = &app;
  std::string path;  // the command words so far, each followed by a space
  for (int i = 1; at->get_require_subcommand_min() > 0; ++i) {
    std::string names, nearest;
    std::size_t best = 3;  // suggest only within two edits
    const std::string word = i < argc ? argv[i] : "";
    CLI::App* found = nullptr;
    for (CLI::App* c : at->get_subcommands([](CLI::App*) { return true; })) {
      names += (names.empty() ? "" : ", ") + c->get_name();
      if (i < argc && c->check_name(word)) found = c;
      if (const std::size_t d = edit_distance(word, c->get_name()); i < argc && d < best) best = d, nearest = c->get_name();
    }
    const std::string of = path.empty() ? "" : " of '" + path.substr(0, path.size() - 1) + "'";
    if (i >= argc) return fmt::format("a command is missing; the commands{} are {}", of, names);
    if (word.empty() || word[0] == '-') return std::nullopt;  // an option (--help, --version): CLI11 handles it
    if (!found)
      return fmt::format("unknown command '{}{}'; the commands{} are {}{}", path, word, of, names,
                         nearest.empty() ? "" : fmt::format(" (did you mean '{}{}'?)", path, nearest));
    path += word + " ";
    at = found;
  }
  return std::nullopt;
}

/// For a command line with an option its command does not have (CLI11 says
/// only "The following arguments were not expected"): the error line
/// naming the command and each unknown option, with the nearest option of
/// that command when one lies within two edits, or one for a name of up to
/// four letters (`--widht` -> `--width`).
std::optional<std::string> unknown_options(const CLI::App& app) {
  const CLI::App* at = &app;  // the command that was parsed, deepest first
  for (bool deeper = true; deeper;) {
    deeper = false;
    for (const CLI::App* c : at->get_subcommands()) at = c, deeper = true;
  }
  std::string line;
  for (const std::string& arg : at->remaining(true)) {
    if (arg.size() < 2 || arg[0] != '-' || (arg[1] >= '0' && arg[1] <= '9')) continue;  // a value, or a number
    const std::string name = arg.substr(0, arg.find('='));
    std::string nearest;
    std::size_t best = name.size() > 6 ? 3 : 2;  // suggest within two edits, one for a short name
    for (const CLI::Option* o : at->get_options())
      for (const std::string& l : o->get_lnames())
        if (const std::size_t d = edit_distance(name, "--" + l); d < best) best = d, nearest = "--" + l;
    line += fmt::format("{}unknown option '{}'{}", line.empty() ? "" : "; ", name,
                        nearest.empty() ? "" : fmt::format(" (did you mean '{}'?)", nearest));
  }
  if (line.empty()) return std::nullopt;
  std::string path = at->get_name();
  for (const CLI::App* p = at->get_parent(); p && p->get_parent(); p = p->get_parent()) path = p->get_name() + " " + path;
  return fmt::format("{}: {}", path, line);
}

/// glibc's allocator returns a freed block of 128 KiB or more to the
/// operating system at once (mmap/munmap, and a trim of the heap's top),
/// so the next such block is faulted in again, page by page: a grid build's
/// per-cell scratch arrays and its copies of the scene's lists paid a fifth
/// of their time in page faults. Blocks below 64 MiB now come from the heap
/// and up to 128 MiB of freed memory is kept for reuse (docs/architecture.md,
/// "Build, install and the run record"). Other C libraries ignore this.
void keep_freed_memory() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_THRESHOLD, 64 << 20);
  mallopt(M_TRIM_THRESHOLD, 128 << 20);
  mallopt(M_TOP_PAD, 64 << 20);
#endif
}

}  // namespace

static int run_main(int argc, char** argv) {
  using namespace raynode;
  apps::mark_process_start();  // --timeout counts from here
  apps::install_cleanup_handlers();
  CLI::App app{"raynode: the parallel ray tracers of Badouel, Bouatouch and Priol (IEEE CG&A 1994) on an "
               "emulated distributed-memory machine"};
  app.require_subcommand(1);
  apps::use_wrapping_help(app);
  apps::record_command_line(argc, argv);
  app.set_version_flag("--version", std::string("raynode ") + apps::version());
  apps::register_scene_commands(app);
  apps::register_validate_command(app);
  apps::register_bench_command(app);
  apps::register_bench_nodes_commands(app);
  apps::register_bench_mpi_command(app);
  apps::register_render_command(app);
  apps::register_sweep_commands(app);
  apps::register_bench_quality_command(app);
  apps::register_bench_cost_model_command(app);
  apps::group_options(app);
  if (const std::optional<std::string> unknown = unknown_command(app, argc, argv)) {
    fmt::print(stderr, "raynode: error: {}\nRun 'raynode --help' (or 'raynode COMMAND --help') for usage.\n", *unknown);
    return 2;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    const std::optional<std::string> unknown =
        e.get_exit_code() == int(CLI::ExitCodes::ExtrasError) ? unknown_options(app) : std::optional<std::string>();
    fmt::print(stderr, "raynode: error: {}\nRun 'raynode --help' (or 'raynode COMMAND --help') for usage.\n",
               unknown ? *unknown : std::string(e.what()));
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

int main(int argc, char** argv) {
  keep_freed_memory();
  const int rc = run_main(argc, argv);
  raynode::apps::end_transport_session(rc);  // MPI: finalize, or end the other ranks after a failure
  return rc;
}
