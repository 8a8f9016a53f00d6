// The plotting script of `raynode bench quality` (apps/cmd_bench_quality.cpp):
// Python + matplotlib, embedded here and written next to the CSV it plots
// as PREFIX.plot.py, then run through run_plot_script (apps/plot.h). It
// reads only the CSV, so it can be re-run by hand later:
//     python3 PREFIX.plot.py PREFIX.csv PREFIX.png TITLE SUBTITLE
// It draws render time against image error, the Pareto front marked.
#pragma once

#include <string_view>

namespace raynode::apps {

/// The script's source (Python 3, matplotlib with the Agg backend).
std::string_view quality_plot_script();

}  // namespace raynode::apps
