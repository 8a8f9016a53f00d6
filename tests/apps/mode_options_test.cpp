// apps/options.cpp: check_mode_options refuses an option that none of the
// given modes reads, and lets through every option that one of them reads.
#include <doctest/doctest.h>

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "apps/commands.h"

using namespace raynode;

namespace {

/// The defaults of the two options whose values check_mode_options reads.
struct Defaults {
  std::string submaps = "square";
  std::string network = "none";
};

/// A command with every mode-dependent option (as render has them; --submaps
/// and --network with `values` as their defaults), parsed from `args`;
/// returns the message of check_mode_options, "" if it passed.
std::string check(const std::vector<std::string>& args, const std::vector<std::string>& modes,
                  Defaults values = {}) {
  CLI::App app;
  std::string text;
  for (const char* name : {"--node-memory", "--network-scale", "--topology", "--schedule-window", "--mail-wakeups",
                           "--clock", "--stall-timeout", "--timeout", "--work-item", "--work-requests",
                           "--work-grants", "--page-size", "--cache", "--directory-order", "--partition",
                           "--queue-capacity", "--subsample"})
    app.add_option(name, text);
  app.add_option("--submaps", values.submaps)->capture_default_str();
  app.add_option("--network", values.network)->capture_default_str();
  std::vector<std::string> argv(args.rbegin(), args.rend());  // CLI11 takes them reversed
  app.parse(argv);
  try {
    apps::check_mode_options(app, modes);
  } catch (const apps::UsageError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("mode options: an option no given mode reads is refused, naming the option, its modes and the mode") {
  CHECK(check({"--cache", "3"}, {"dataflow"}) ==
        "--cache is for --mode svm (the shared virtual memory's page cache), not --mode dataflow; leave --cache out");
  CHECK(check({"--partition", "equal"}, {"svm"}).starts_with("--partition is for --mode dataflow (its regions), not "
                                                             "--mode svm"));
  CHECK(check({"--work-grants", "half"}, {"dataflow"})
            .starts_with("--work-grants is for --mode replicated or svm (static submaps and work requests)"));
  CHECK(check({"--node-memory", "1MiB"}, {"sequential"})
            .starts_with("--node-memory is for --mode replicated, svm or dataflow"));
  CHECK(check({"--clock", "model"}, {"shared"}).find("not --mode shared") != std::string::npos);
  CHECK(check({"--queue-capacity", "4"}, {"svm", "replicated"}).find("not --modes svm,replicated") !=
        std::string::npos);
  CHECK(check({"--directory-order", "bricked"}, {"replicated"}).starts_with("--directory-order is for --mode svm"));
}

TEST_CASE("mode options: every option a given mode reads passes, and options not given are not checked") {
  CHECK(check({}, {"sequential"}) == "");
  CHECK(check({"--timeout", "5"}, {"sequential"}) == "");  // every mode has a time limit
  CHECK(check({"--cache", "3", "--page-size", "512", "--directory-order", "linear"}, {"svm"}) == "");
  CHECK(check({"--partition", "equal", "--queue-capacity", "4"}, {"dataflow"}) == "");
  CHECK(check({"--work-item", "4x4", "--work-requests", "off", "--submaps", "balanced"}, {"replicated"}) == "");
  CHECK(check({"--node-memory", "1MiB", "--clock", "model", "--stall-timeout", "9"}, {"dataflow"}) == "");
  // A sweep over several modes: read by one of them is enough.
  CHECK(check({"--cache", "3", "--partition", "equal"}, {"svm", "dataflow", "replicated"}) == "");
}

TEST_CASE("mode options: --subsample and --network-scale are refused where what reads them is off") {
  // --subsample: dataflow's estimate, or balanced submaps' in replicated and svm.
  CHECK(check({"--subsample", "4"}, {"dataflow"}) == "");
  CHECK(check({"--subsample", "4"}, {"svm"}, {.submaps = "balanced"}) == "");
  CHECK(check({"--subsample", "4"}, {"svm"}, {.submaps = "square"}).find("not --mode svm with --submaps square") !=
        std::string::npos);
  CHECK(check({"--subsample", "4"}, {"sequential"}, {.submaps = "balanced"}).starts_with("--subsample is for"));
  // --network-scale: only the ipsc2 model scales to this machine.
  CHECK(check({"--network-scale", "0.01"}, {"svm"}, {.network = "ipsc2"}) == "");
  CHECK(check({"--network-scale", "0.01"}, {"svm"}, {.network = "cluster"}) ==
        "--network-scale is for --network ipsc2 (this machine's seconds per ray), not --network cluster; leave "
        "--network-scale out");
}

namespace {

/// The message of `check` on `text`, "" if it passes.
std::string validate(const CLI::Validator& check, std::string text) { return check(text); }

}  // namespace

TEST_CASE("finite range: NaN and infinities are refused where CLI::Range lets NaN through") {
  const CLI::Validator unit = apps::finite_range(0, 1);
  CHECK(validate(unit, "0") == "");
  CHECK(validate(unit, "0.25") == "");
  CHECK(validate(unit, "1") == "");
  CHECK(validate(unit, "nan") == "must be a finite number in [0, 1], got 'nan'");
  CHECK(validate(unit, "-nan") != "");
  CHECK(validate(unit, "inf") != "");
  CHECK(validate(unit, "1.5") != "");
  CHECK(validate(unit, "-0.1") != "");
  CHECK(validate(unit, "0.5x") != "");
  CHECK(validate(unit, "") != "");
  // CLI::Range itself passes NaN: the reason for finite_range.
  std::string nan = "nan";
  CHECK(CLI::Range(0.0, 1.0)(nan) == "");
  // Open bounds.
  const CLI::Validator at_least_0 = apps::finite_range(0, apps::kNoBound);
  CHECK(validate(at_least_0, "1e300") == "");
  CHECK(validate(at_least_0, "inf") == "must be a finite number >= 0, got 'inf'");
  const CLI::Validator any = apps::finite_range(-apps::kNoBound, apps::kNoBound);
  CHECK(validate(any, "-200") == "");
  CHECK(validate(any, "nan") == "must be a finite number, got 'nan'");
  CHECK(validate(any, "-inf") != "");
  const CLI::Validator positive = apps::finite_positive();
  CHECK(validate(positive, "1e-9") == "");
  CHECK(validate(positive, "0") == "must be a finite number > 0, got '0'");
  CHECK(validate(positive, "nan") != "");
  CHECK(validate(positive, "inf") != "");
}
