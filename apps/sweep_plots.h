// The plotting script of `raynode sweep` (apps/cmd_sweep.cpp): Python +
// matplotlib, embedded here and written next to the CSV it plots as
// PREFIX.plot.py, then run through run_plot_script (apps/plot.h). It reads
// only the CSV, so it can be re-run by hand later:
//     python3 PREFIX.plot.py PREFIX.csv PREFIX.png KIND TITLE
// KIND "nodes": speedup (with the ideal line) and efficiency against node
// count, log2 axes, one curve per mode (the paper's Figures 5 and 7).
// KIND "cache": efficiency, miss ratio and communication rate against the
// cache size in percent of the database (Figures 8, 9 and 10).
// KIND "page-size": efficiency, miss ratio, pages per pixel and
// communication rate against page size (log2 axis).
// Points whose status is not "ok" (skipped: did not fit a node) are left out
// of the curves and named under the figure.
#pragma once

#include <string_view>

namespace raynode::apps {

/// The script's source (Python 3, matplotlib with the Agg backend).
std::string_view sweep_plot_script();

}  // namespace raynode::apps
