// Randomised robustness tests for the NFF reader: mutated and truncated
// inputs must either parse into a scene that round-trips through the writer,
// or throw ParseError located inside the text. Deterministic (fixed seeds).
#include <doctest/doctest.h>

#include <algorithm>
#include <cctype>
#include <cstddef>
#include <random>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "core/nff.h"

namespace {

using raynode::core::ParseError;
using raynode::core::parse_nff;
using raynode::core::Scene;

const char* const kBase =
    "# every entity once\n"
    "b 0.078 0.361 0.753\n"
    "v\nfrom 1 2 3\nat 0 0 0\nup 0 0 1\nangle 45\nhither 1\nresolution 64 48\n"
    "l 3 -2.6 3\nl 1 1 1 0.5 0.5 0.5\n"
    "f 1 0.2 0.2 1 0 100000 0 0\n"
    "p 4\n-1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n"
    "f 1 1 1 0.1 0.1 101.148 0.9 1.5\n"
    "pp 3\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 -0 0 1\n"
    "s 0.930995 2.61313 0 0.07412\n"
    "c\n0 0 0 1\n0 2 0 0.5\n"
    "c 0.287693 3.49855 0 0.07412 -2.55836e-17 2.0659 0 0.07412\n";

std::string to_nff(const Scene& s) {
  std::ostringstream out;
  raynode::core::write_nff(out, s);
  return out.str();
}

/// Lines in `text`, counting a final line without a newline.
int line_count(std::string_view text) {
  return static_cast<int>(std::count(text.begin(), text.end(), '\n')) + 1;
}

/// Parses `text`; returns "" when it behaved, else what went wrong.
std::string check_behaviour(const std::string& text) {
  try {
    const Scene s = parse_nff(text, "fuzz.nff");
    // A scene the reader accepted must survive the writer unchanged.
    const std::string once = to_nff(s);
    const std::string twice = to_nff(parse_nff(once, "rewritten.nff"));
    if (once != twice) return "round trip changed the scene";
  } catch (const ParseError& e) {
    if (e.line() < 1 || e.line() > line_count(text)) return "line out of range: " + std::string(e.what());
    if (e.column() < 1) return "column out of range: " + std::string(e.what());
    if (std::string_view(e.what()).substr(0, 9) != "fuzz.nff:") return "bad prefix: " + std::string(e.what());
    if (e.message().empty()) return "empty message";
  } catch (const std::exception& e) {
    return std::string("unexpected exception: ") + e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("nff fuzzish: the base scene itself parses and round-trips") {
  CHECK(check_behaviour(kBase) == "");
  CHECK(parse_nff(kBase).counts().cones == 2);
}

TEST_CASE("nff fuzzish: every truncation either parses or throws ParseError inside the text") {
  const std::string base = kBase;
  int errors = 0;
  for (std::size_t n = 0; n <= base.size(); ++n) {
    const std::string text = base.substr(0, n);
    CAPTURE(text);
    REQUIRE(check_behaviour(text) == "");
    try {
      parse_nff(text);
    } catch (const ParseError&) {
      ++errors;
    }
  }
  // Most cut points fall inside an entity; the reader must notice.
  CHECK(errors > static_cast<int>(base.size()) / 2);
}

TEST_CASE("nff fuzzish: random byte and token mutations never escape as other exceptions") {
  const std::string base = kBase;
  const std::string alphabet = " \n\t#-+.eE0123456789abcfilnpsvx";
  const std::vector<std::string> words = {"nan", "inf", "-1", "0", "1e39", "1e-50", "x", "p",
                                          "pp", "3", "2", "c", "v", "#", "9999999", "-0", ""};
  std::mt19937 rng(12345);
  auto pick = [&](std::size_t n) { return std::uniform_int_distribution<std::size_t>(0, n - 1)(rng); };
  for (int iter = 0; iter < 3000; ++iter) {
    std::string text = base;
    const int edits = 1 + static_cast<int>(pick(3));
    for (int e = 0; e < edits && !text.empty(); ++e) {
      const std::size_t at = pick(text.size());
      switch (pick(4)) {
        case 0: text.erase(at, 1); break;
        case 1: text.insert(text.begin() + static_cast<std::ptrdiff_t>(at), alphabet[pick(alphabet.size())]); break;
        case 2: text[at] = alphabet[pick(alphabet.size())]; break;
        case 3: {  // replace the token around `at` with a chosen word
          std::size_t b = at, end = at;
          while (b > 0 && !std::isspace(static_cast<unsigned char>(text[b - 1]))) --b;
          while (end < text.size() && !std::isspace(static_cast<unsigned char>(text[end]))) ++end;
          text.replace(b, end - b, words[pick(words.size())]);
          break;
        }
      }
    }
    CAPTURE(iter);
    CAPTURE(text);
    REQUIRE(check_behaviour(text) == "");
  }
}
