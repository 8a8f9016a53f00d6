// `raynode bench quality SCENE`: run time against image error (issue 7).
// Placeholder until filled.
#include "apps/commands.h"

namespace raynode::apps {

void register_bench_quality_command(CLI::App& app) { (void)app; }

}  // namespace raynode::apps
