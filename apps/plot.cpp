#include "apps/plot.h"

#include "apps/commands.h"

#include <sys/wait.h>

#include <csignal>
#include <cstdlib>
#include <fstream>
#include <stdexcept>

namespace raynode::apps {

namespace {

std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) {
    if (c == '\'') q += "'\\''";
    else q += c;
  }
  return q + "'";
}

/// True when std::system's status says the child died of SIGINT (Ctrl-C),
/// itself or through the shell (exit status 130).
bool interrupted(int status) {
  return status != -1 && ((WIFSIGNALED(status) && WTERMSIG(status) == SIGINT) ||
                          (WIFEXITED(status) && WEXITSTATUS(status) == 128 + SIGINT));
}

/// std::system ignores SIGINT in this process while the child runs; a
/// Ctrl-C that ended the child ends the command too.
int run_command(const std::string& cmd, const std::string& what) {
  const int status = std::system(cmd.c_str());
  if (interrupted(status)) throw Interrupted("interrupted (Ctrl-C) while " + what);
  return status;
}

bool python_has_matplotlib(const std::string& python) {
  const std::string cmd = python + " -c 'import matplotlib' >/dev/null 2>&1";
  return run_command(cmd, "looking for matplotlib") == 0;
}

}  // namespace

PlotOutcome run_plot_script(std::string_view script, const std::string& script_path,
                            const std::vector<std::string>& args) {
  PlotOutcome out;
  out.script_path = script_path;
  {
    std::ofstream f(script_path, std::ios::binary | std::ios::trunc);
    if (!f) throw std::runtime_error("cannot write the plot script " + script_path);
    f.write(script.data(), std::streamsize(script.size()));
    if (!f) throw std::runtime_error("cannot write the plot script " + script_path);
  }
  std::string tail = " " + shell_quote(script_path);
  for (const std::string& a : args) tail += " " + shell_quote(a);
  out.command = "python3" + tail;
  // $RAYNODE_PYTHON, when set, is the only interpreter tried.
  std::vector<std::string> pythons{"/usr/bin/python3", "python3"};
  if (const char* chosen = std::getenv("RAYNODE_PYTHON"); chosen && *chosen) pythons = {chosen};
  for (const std::string& python : pythons) {
    if (!python_has_matplotlib(python)) continue;
    out.command = python + tail;
    const int status = run_command(out.command, "plotting; the CSV is complete, to plot it later: " + out.command);
    out.ran = status == 0;
    if (!out.ran)
      out.message = "the plot script failed (" +
                    (WIFEXITED(status) ? "exit status " + std::to_string(WEXITSTATUS(status))
                                       : "status " + std::to_string(status)) +
                    ")";
    return out;
  }
  out.message = "no python3 with matplotlib found (Debian: apt-get install python3-matplotlib)";
  return out;
}

}  // namespace raynode::apps
