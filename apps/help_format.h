// How `--help` reads: options listed under groups (scene, image, mode,
// machine, svm, dataflow, output) and descriptions wrapped to the terminal.
#pragma once

#include <CLI/CLI.hpp>

namespace raynode::apps {

/// Sets a formatter on `app` that wraps option descriptions to the
/// terminal's width (stdout's, else $COLUMNS, else 100 columns). Call
/// before adding subcommands: they copy their parent's formatter.
void use_wrapping_help(CLI::App& app);

/// Puts every option of `app` and of its subcommands, at any depth, in its
/// help group, from one table of option names (help_format.cpp); options
/// the table does not name stay under "Options".
void group_options(CLI::App& app);

}  // namespace raynode::apps
