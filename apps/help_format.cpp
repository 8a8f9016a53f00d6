#include "apps/help_format.h"

#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <map>
#include <memory>
#include <sstream>
#include <string>

namespace raynode::apps {

namespace {

/// Columns of the terminal on stdout, else $COLUMNS, else 100; at least 60.
std::size_t terminal_columns() {
  winsize ws{};
  if (::isatty(STDOUT_FILENO) && ::ioctl(STDOUT_FILENO, TIOCGWINSZ, &ws) == 0 && ws.ws_col > 0)
    return std::max<std::size_t>(60, ws.ws_col);
  if (const char* env = std::getenv("COLUMNS")) {
    const long c = std::strtol(env, nullptr, 10);
    if (c > 0) return std::max<std::size_t>(60, std::size_t(c));
  }
  return 100;
}

/// `text` broken at spaces into lines of at most `width` characters (a
/// longer word stands alone); existing line breaks are kept.
std::string wrap(const std::string& text, std::size_t width) {
  std::string out, line;
  std::istringstream paragraphs(text);
  std::string paragraph;
  bool first_paragraph = true;
  while (std::getline(paragraphs, paragraph)) {
    if (!first_paragraph) out += '\n';
    first_paragraph = false;
    std::istringstream words(paragraph);
    std::string word;
    line.clear();
    while (words >> word) {
      if (!line.empty() && line.size() + 1 + word.size() > width) {
        out += line + '\n';
        line.clear();
      }
      line += (line.empty() ? "" : " ") + word;
    }
    out += line;
  }
  return out;
}

class WrappingFormatter : public CLI::Formatter {
 public:
  WrappingFormatter() { column_width(32); }
  std::string make_option_desc(const CLI::Option* opt) const override {
    const std::size_t columns = terminal_columns();
    const std::size_t width = columns > get_column_width() + 20 ? columns - get_column_width() - 1 : 40;
    return wrap(opt->get_description(), width);
  }
};

/// Each option's help group, by its long name (or positional name).
const std::map<std::string, std::string>& option_groups() {
  static const std::map<std::string, std::string> groups = {
      // The scene and the view
      {"tessellate", "Scene"}, {"scale", "Scene"}, {"translate", "Scene"}, {"eye", "Scene"},
      {"at", "Scene"}, {"up", "Scene"}, {"fov", "Scene"},
      // The picture
      {"width", "Image"}, {"height", "Image"}, {"spp", "Image"}, {"max-depth", "Image"},
      {"min-weight", "Image"},
      // How it is computed
      {"mode", "Mode"}, {"modes", "Mode"}, {"nodes", "Mode"}, {"accel", "Mode"}, {"grid", "Mode"},
      {"skip-empty", "Mode"}, {"pack-cells", "Mode"},
      // The emulated machine
      {"machine", "Machine"}, {"node-memory", "Machine"}, {"network", "Machine"}, {"network-scale", "Machine"}, {"contention", "Machine"},
      {"topology", "Machine"}, {"clock", "Machine"}, {"corun-slowdown", "Machine"}, {"calibrate", "Machine"},
      {"schedule-window", "Machine"},
      {"mail-wakeups", "Machine"}, {"stall-timeout", "Machine"}, {"work-item", "Machine"},
      {"work-requests", "Machine"}, {"work-grants", "Machine"}, {"submaps", "Machine"},
      // The paper's two algorithms
      {"page-size", "svm"}, {"directory-order", "svm"}, {"primitive-order", "svm"}, {"cache", "svm"}, {"caches", "svm"},
      {"page-sizes", "svm"},
      {"subsample", "dataflow"}, {"partition", "dataflow"}, {"queue-capacity", "dataflow"}, {"send-queue", "dataflow"},
      // What is written, and when to stop
      {"output", "Output"}, {"stats", "Output"}, {"aov", "Output"}, {"json", "Output"}, {"csv", "Output"},
      {"quiet", "Output"}, {"timeout", "Output"}, {"plot", "Output"},
  };
  return groups;
}

}  // namespace

void use_wrapping_help(CLI::App& app) { app.formatter(std::make_shared<WrappingFormatter>()); }

void group_options(CLI::App& app) {
  const auto& groups = option_groups();
  for (CLI::Option* opt : app.get_options()) {
    if (opt->get_positional() || opt->get_lnames().empty()) continue;
    if (const auto it = groups.find(opt->get_lnames().front()); it != groups.end()) opt->group(it->second);
  }
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) group_options(*sub);
}

}  // namespace raynode::apps
