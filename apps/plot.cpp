#include "apps/plot.h"

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

bool python_has_matplotlib(const std::string& python) {
  const std::string cmd = python + " -c 'import matplotlib' >/dev/null 2>&1";
  return std::system(cmd.c_str()) == 0;
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
  for (const char* python : {"/usr/bin/python3", "python3"}) {
    if (!python_has_matplotlib(python)) continue;
    out.command = std::string(python) + tail;
    const int rc = std::system(out.command.c_str());
    out.ran = rc == 0;
    if (!out.ran) out.message = "the plot script failed (exit status " + std::to_string(rc) + ")";
    return out;
  }
  out.message = "no python3 with matplotlib found (Debian: apt-get install python3-matplotlib)";
  return out;
}

}  // namespace raynode::apps
