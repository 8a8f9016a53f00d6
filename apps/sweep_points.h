// The points of a sweep, from the command line (apps/cmd_sweep.cpp, bench
// nodes): lists of node counts, page sizes and cache sizes, with ranges.
// Pure parsing: no scene, no machine; every bad text throws UsageError
// (exit 2) naming the option and the offending item.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace raynode::apps {

/// A list of whole numbers in [lo, hi]: "1,2,4,8", or a range of powers of
/// two "1..64" (both ends included; ends need not be powers of two: 3..20 =
/// 3,4,8,16,20), mixed freely ("1,3..16"); sorted, duplicates dropped.
/// Throws UsageError naming `option` for an empty list, a value out of
/// range or bad syntax.
std::vector<std::uint32_t> parse_count_list(const std::string& text, const char* option, std::uint32_t lo,
                                            std::uint32_t hi);

/// parse_count_list for node counts: 1 .. nodes::kMaxNodes, with "0" named
/// as a machine without nodes.
std::vector<std::uint32_t> parse_node_list(const std::string& text, const char* option = "--nodes");

/// One cache size per node of `sweep cache` (svm::SvmParams::cache_pages /
/// cache_fraction); exactly one of fraction, pages, max is set.
struct CachePoint {
  std::string label;        ///< canonical text: "5%", "204p", "max"
  double fraction = 0;      ///< of the database's pages, in (0, 1], when > 0
  std::uint32_t pages = 0;  ///< cache frames per node, when > 0
  bool max = false;         ///< all the memory a node has left (svm's default)
};

/// Cache sizes, comma-separated: a number is a percentage of the database's
/// pages in (0, 100] ('%' optional); "A..B%" = A, the 1-2-5 series strictly
/// between A and B (.., 0.5, 1, 2, 5, 10, 20, 50, ..), and B; "A..B:N%" = N
/// evenly spaced values from A to B (2 <= N <= 1000); "Np" = N pages;
/// "max". In the given order, repeats (same label) dropped. Throws
/// UsageError naming `option`.
std::vector<CachePoint> parse_cache_points(const std::string& text, const char* option = "--cache");

}  // namespace raynode::apps
