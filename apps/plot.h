// Plots for the experiment commands (sweep, bench quality): a Python
// script that uses matplotlib (Debian: python3-matplotlib) is embedded in
// the program, written next to the CSV it plots, and run. Without a Python
// that has matplotlib the CSV still stands and the caller prints how to
// plot it later.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace raynode::apps {

/// What run_plot_script did.
struct PlotOutcome {
  bool ran = false;           ///< the script ran and exited 0
  std::string script_path;    ///< where the script was written
  std::string command;        ///< the command line that runs it (to print on failure)
  std::string message;        ///< why it did not run, when !ran
};

/// Writes `script` (Python source) to `script_path`, then runs it with the
/// first Python 3 that can import matplotlib (/usr/bin/python3, then
/// python3 on PATH; only $RAYNODE_PYTHON when it is set) and `args` (each
/// shell-quoted). Never throws for a missing Python or matplotlib; throws
/// std::runtime_error if the script file cannot be written, and
/// Interrupted (exit 130) when Ctrl-C ended the script.
PlotOutcome run_plot_script(std::string_view script, const std::string& script_path,
                            const std::vector<std::string>& args);

}  // namespace raynode::apps
