// `raynode sweep nodes|cache|page-size SCENE`: the paper's experiments as
// commands (issue 7). Placeholder until filled.
#include "apps/commands.h"

namespace raynode::apps {

void register_sweep_commands(CLI::App& app) { (void)app; }

}  // namespace raynode::apps
