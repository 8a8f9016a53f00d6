// What a JSON report says about the run itself: the program's version
// (`git describe` at build time), the command line, and the host machine
// the run took place on. Every JSON the commands write carries it under
// "run", so a results file says what produced it.
#pragma once

#include <nlohmann/json_fwd.hpp>
#include <string>

namespace raynode::apps {

/// The program's version: "0.1.0+g<commit>[-dirty]", or the tag's text on a
/// tagged commit, or the project version where the source had no git history.
const char* version();

/// Records argv for run_json(); main() calls it once before parsing.
void record_command_line(int argc, char** argv);

/// {"version", "command_line" (the words, shell-quoted where needed, as one
/// string), "host": {"cpu" (model name), "logical_cpus", "os" (sysname and
/// release)}, "arch" (the -march the build used)}.
nlohmann::json run_json();

}  // namespace raynode::apps
