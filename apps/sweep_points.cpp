#include "apps/sweep_points.h"

#include <fmt/core.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>

#include "apps/commands.h"
#include "nodes/machine.h"

namespace raynode::apps {

namespace {

/// A whole number in [lo, hi] from `text`; throws UsageError naming `option`.
std::uint32_t parse_count(const std::string& text, const char* option, std::uint32_t lo, std::uint32_t hi) {
  char* end = nullptr;
  errno = 0;
  const unsigned long long v = std::strtoull(text.c_str(), &end, 10);
  if (text.empty() || !std::isdigit(static_cast<unsigned char>(text[0])) || *end != '\0' || errno == ERANGE)
    throw UsageError(fmt::format("{}: '{}' is not a whole number", option, text));
  if (v < lo || v > hi) throw UsageError(fmt::format("{}: {} is out of range {}..{}", option, v, lo, hi));
  return std::uint32_t(v);
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t") - b + 1);
}

}  // namespace

std::vector<std::uint32_t> parse_count_list(const std::string& text, const char* option, std::uint32_t lo,
                                            std::uint32_t hi) {
  if (text.find_first_not_of(" \t,") == std::string::npos)
    throw UsageError(fmt::format("{}: the list is empty (e.g. 1,2,4,8 or 1..64)", option));
  std::vector<std::uint32_t> out;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t comma = std::min(text.find(',', start), text.size());
    const std::string item = trim(text.substr(start, comma - start));
    start = comma + 1;
    if (item.empty()) throw UsageError(fmt::format("{}: empty item in '{}'", option, text));
    const std::size_t dots = item.find("..");
    if (dots == std::string::npos) {
      out.push_back(parse_count(item, option, lo, hi));
      continue;
    }
    const std::uint32_t a = parse_count(trim(item.substr(0, dots)), option, lo, hi);
    const std::uint32_t b = parse_count(trim(item.substr(dots + 2)), option, lo, hi);
    if (a > b) throw UsageError(fmt::format("{}: range '{}' runs backwards", option, item));
    out.push_back(a);
    for (std::uint64_t p = 1; p <= b; p *= 2)
      if (p > a) out.push_back(std::uint32_t(p));
    out.push_back(b);
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

std::vector<std::uint32_t> parse_node_list(const std::string& text, const char* option) {
  std::size_t start = 0;
  while (start <= text.size()) {  // name a zero before the generic range message
    const std::size_t comma = std::min(text.find(',', start), text.size());
    const std::string item = trim(text.substr(start, comma - start));
    if (!item.empty() && item.find_first_not_of('0') == std::string::npos)
      throw UsageError(fmt::format("{}: a machine needs at least 1 node, got {}", option, item));
    start = comma + 1;
  }
  return parse_count_list(text, option, 1, nodes::kMaxNodes);
}

std::vector<CachePoint> parse_cache_points(const std::string& text, const char* option) {
  auto bad = [&](const std::string& why) {
    return UsageError(fmt::format("{}: {} in '{}' (e.g. 1,2,5,10,20,50,100%, 1..100%, 5..70:8%, 204p, max)", option,
                                  why, text));
  };
  auto number = [&](std::string s) {
    while (!s.empty() && (s.back() == ' ' || s.back() == '%')) s.pop_back();
    s.erase(0, s.find_first_not_of(' '));
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    if (s.empty() || *end != '\0' || !std::isfinite(v)) throw bad("'" + s + "' is not a number");
    return v;
  };
  auto percent = [&](double v) {
    if (!(v > 0 && v <= 100)) throw bad(fmt::format("a percentage must be in (0, 100], got {:g}", v));
    CachePoint p;
    p.label = fmt::format("{:g}%", v);
    p.fraction = v / 100.0;
    return p;
  };
  std::vector<CachePoint> out;
  std::size_t start = 0;
  if (text.find_first_not_of(" ,%") == std::string::npos) throw bad("the list is empty");
  while (start <= text.size()) {
    const std::size_t comma = std::min(text.find(',', start), text.size());
    std::string item = text.substr(start, comma - start);
    start = comma + 1;
    item.erase(0, item.find_first_not_of(' '));
    item.erase(item.find_last_not_of(' ') + 1);
    if (item.empty()) throw bad("an empty item");
    if (item == "max") {
      CachePoint p;
      p.label = "max";
      p.max = true;
      out.push_back(p);
      continue;
    }
    if (item.back() == 'p') {
      const double v = number(item.substr(0, item.size() - 1));
      if (!(v >= 1 && v <= 4294967295.0) || v != std::floor(v)) throw bad("a page count must be a whole number >= 1");
      CachePoint p;
      p.label = fmt::format("{}p", std::uint32_t(v));
      p.pages = std::uint32_t(v);
      out.push_back(p);
      continue;
    }
    const std::size_t dots = item.find("..");
    if (dots == std::string::npos) {
      out.push_back(percent(number(item)));
      continue;
    }
    std::string hi_text = item.substr(dots + 2);
    int steps = 0;  // 0: the 1-2-5 series
    if (const std::size_t colon = hi_text.find(':'); colon != std::string::npos) {
      const double s = number(hi_text.substr(colon + 1));
      if (!(s >= 2 && s <= 1000) || s != std::floor(s)) throw bad("the step count after ':' must be 2..1000");
      steps = int(s);
      hi_text = hi_text.substr(0, colon);
    }
    const double a = number(item.substr(0, dots)), b = number(hi_text);
    percent(a), percent(b);  // range checks
    if (a >= b) throw bad("a range must run upwards");
    std::vector<double> values;
    if (steps > 0) {
      for (int i = 0; i < steps; ++i) values.push_back(a + (b - a) * double(i) / double(steps - 1));
    } else {
      values.push_back(a);
      for (double decade = 1e-3; decade <= 100; decade *= 10)
        for (double k : {1.0, 2.0, 5.0}) {
          const double v = std::round(k * decade * 1e6) / 1e6;
          if (v > a * (1 + 1e-9) && v < b * (1 - 1e-9)) values.push_back(v);
        }
      values.push_back(b);
    }
    for (double v : values) out.push_back(percent(std::round(v * 1e4) / 1e4));
  }
  // Drop repeats (same label), keeping the first.
  std::vector<CachePoint> unique;
  for (const CachePoint& p : out)
    if (std::none_of(unique.begin(), unique.end(), [&](const CachePoint& q) { return q.label == p.label; }))
      unique.push_back(p);
  return unique;
}


}  // namespace raynode::apps
