// NFF reader and writer. See nff.h for the contract and
// docs/nff.md for the format.
//
// Reader: the whole file is read into memory (scene_file.h: inflated first
// when it starts with the gzip magic, within a memory limit), then parsed as
// a stream of whitespace-separated tokens with std::from_chars. `#` starts a
// comment only where a token would start: inside a token it is part of the
// token (so MSVC's `1.#INF` is an error, not the number 1). Only byte offsets
// are tracked while parsing; the 1-based line and column are computed from
// the offset when an error is thrown, so the hot loop pays nothing for
// locations. Parsing polls the stop request (core/stop.h).
//
// Writer: formats into an fmt::memory_buffer and hands it to a sink in large
// chunks (an ostream, a FILE*, or a gzFile). Floats use fmt's shortest
// round-trip representation, so parse_nff(write_nff(s)) reproduces every bit.
#include "core/nff.h"

#include <zlib.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <ostream>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "core/camera.h"
#include "core/database.h"
#include "core/scene_file.h"
#include "core/stop.h"

namespace raynode::core {

ParseError::ParseError(std::string file, int line, int column, const std::string& message)
    : std::runtime_error(fmt::format("{}:{}:{}: {}", file, line, column, message)),
      file_(std::move(file)),
      line_(line),
      column_(column),
      message_(message) {}

namespace {

/// Polygon/patch vertex counts above this are reported, not allocated.
constexpr long long kMaxPolygonVertices = 10'000'000;
/// Largest view resolution per side, as the CLI's --width/--height allow
/// (a 100000 x 100000 view would ask for 120 GB of pixels).
constexpr long long kMaxResolution = 16384;

// ---------------------------------------------------------------------------
// Lexer
// ---------------------------------------------------------------------------

/// Character classes: 0 = token character, 1 = whitespace, 2 = '#' (a
/// comment where a token would start; a token character inside a token).
constexpr std::array<std::uint8_t, 256> make_char_classes() {
  std::array<std::uint8_t, 256> t{};
  for (unsigned char c : {' ', '\t', '\n', '\r', '\f', '\v'}) t[c] = 1;
  t[static_cast<unsigned char>('#')] = 2;
  return t;
}
constexpr std::array<std::uint8_t, 256> kCharClass = make_char_classes();

/// Ends a token: whitespace only ('#' inside a token belongs to it).
inline bool is_delimiter(char c) { return kCharClass[static_cast<unsigned char>(c)] == 1; }

/// How a numeric token failed to convert.
enum class NumberStatus { kOk, kNotANumber, kNotFinite };

/// True when a decimal token that std::from_chars accepted whole (sign,
/// digits, optional '.' digits, optional exponent) has a magnitude below 1:
/// its leading digit's power of ten, plus the exponent, is negative. The
/// exponent saturates, so 1e-99999999999999999999 is still below 1.
bool magnitude_below_one(std::string_view tok) {
  std::size_t i = 0;
  if (i < tok.size() && (tok[i] == '+' || tok[i] == '-')) ++i;
  bool found = false, after_point = false;
  long long int_digits = 0, frac_zeros = 0;
  for (; i < tok.size(); ++i) {
    const char c = tok[i];
    if (c == '.') {
      after_point = true;
      continue;
    }
    if (c < '0' || c > '9') break;
    if (!after_point) {
      if (found || c != '0') found = true, ++int_digits;
    } else if (!found) {
      if (c != '0') found = true;
      else ++frac_zeros;
    }
  }
  if (!found) return true;  // all zeros
  const long long lead = int_digits > 0 ? int_digits - 1 : -frac_zeros - 1;  // power of ten of the first digit
  long long exp = 0;
  if (i < tok.size() && (tok[i] == 'e' || tok[i] == 'E')) {
    ++i;
    bool negative = false;
    if (i < tok.size() && (tok[i] == '+' || tok[i] == '-')) negative = tok[i++] == '-';
    for (; i < tok.size() && tok[i] >= '0' && tok[i] <= '9'; ++i) {
      exp = std::min(exp * 10 + (tok[i] - '0'), 1'000'000'000'000LL);
    }
    if (negative) exp = -exp;
  }
  return lead + exp < 0;
}

/// MSVC's spellings of infinities and NaNs after a number: 1.#INF, 1.#IND,
/// 1.#QNAN, 1.#SNAN (any case, any suffix).
bool is_msvc_non_finite(std::string_view rest) {
  if (rest.empty() || rest[0] != '#') return false;
  std::string up;
  for (std::size_t i = 1; i < rest.size() && i < 5; ++i) {
    up += static_cast<char>(std::toupper(static_cast<unsigned char>(rest[i])));
  }
  return up.rfind("INF", 0) == 0 || up.rfind("IND", 0) == 0 || up.rfind("QNAN", 0) == 0 ||
         up.rfind("SNAN", 0) == 0;
}

/// Converts a whole token to a float. Accepts a leading '+'. A finite
/// decimal too small for float rounds as IEEE 754 round-to-nearest does: to
/// a denormal, or to zero with its sign when below half the smallest
/// denormal (about 7e-46), however small (1e-50 and 1e-400 both read as 0).
/// Rejects nan/inf (also MSVC's 1.#INF) and values that overflow float
/// (above about 3.4e38) as not finite.
NumberStatus token_to_float(std::string_view tok, float& out) {
  const char* first = tok.data();
  const char* last = tok.data() + tok.size();
  if (first != last && *first == '+') ++first;
  auto [ptr, ec] = std::from_chars(first, last, out);
  if (ec == std::errc::result_out_of_range && ptr == last) {
    if (!magnitude_below_one({first, static_cast<std::size_t>(last - first)})) return NumberStatus::kNotFinite;
    out = *first == '-' ? -0.0f : 0.0f;  // underflow: rounds to a signed zero
    return NumberStatus::kOk;
  }
  if (ptr != first && ptr != last && ec != std::errc::invalid_argument &&
      is_msvc_non_finite({ptr, static_cast<std::size_t>(last - ptr)})) {
    return NumberStatus::kNotFinite;
  }
  if (ec != std::errc{} || ptr != last) return NumberStatus::kNotANumber;
  if (!std::isfinite(out)) return NumberStatus::kNotFinite;
  return NumberStatus::kOk;
}

/// Shortens a token for quoting in a message; bytes that are not printable
/// ASCII (binary garbage, control characters) are shown as \xNN.
std::string quote(std::string_view tok) {
  constexpr std::size_t kMax = 40;
  std::string out = "'";
  for (std::size_t i = 0; i < tok.size() && i < kMax; ++i) {
    const auto c = static_cast<unsigned char>(tok[i]);
    if (c >= 0x20 && c < 0x7f) out += static_cast<char>(c);
    else out += fmt::format("\\x{:02x}", c);
  }
  out += tok.size() > kMax ? "...'" : "'";
  return out;
}

/// Token stream over an in-memory NFF text. Owner thread only.
class Lexer {
 public:
  Lexer(std::string_view text, const std::string& name)
      : begin_(text.data()), p_(text.data()), end_(text.data() + text.size()), name_(name) {}

  /// Skips whitespace and comments; true when a token follows.
  bool skip() {
    while (p_ != end_) {
      const std::uint8_t cls = kCharClass[static_cast<unsigned char>(*p_)];
      if (cls == 0) return true;
      if (cls == 1) {
        ++p_;
      } else {
        const void* nl = std::memchr(p_, '\n', static_cast<std::size_t>(end_ - p_));
        p_ = nl ? static_cast<const char*>(nl) : end_;
      }
    }
    return false;
  }

  /// The next token; the lexer must be at a token start (after skip()).
  std::string_view take_token() {
    const char* start = p_;
    while (p_ != end_ && !is_delimiter(*p_)) ++p_;
    return {start, static_cast<std::size_t>(p_ - start)};
  }

  /// The next token without consuming it; empty at end of input.
  std::string_view peek_token() {
    if (!skip()) return {};
    const char* q = p_;
    while (q != end_ && !is_delimiter(*q)) ++q;
    return {p_, static_cast<std::size_t>(q - p_)};
  }

  const char* position() const { return p_; }
  const char* end() const { return end_; }

  /// Throws a ParseError located at `at` (a pointer into the text).
  [[noreturn]] void fail_at(const char* at, const std::string& message) const {
    int line = 1;
    const char* line_start = begin_;
    for (const char* q = begin_; q < at; ++q) {
      if (*q == '\n') {
        ++line;
        line_start = q + 1;
      }
    }
    throw ParseError(name_, line, static_cast<int>(at - line_start) + 1, message);
  }

 private:
  const char* begin_;
  const char* p_;
  const char* end_;
  const std::string& name_;
};

// ---------------------------------------------------------------------------
// Parser
// ---------------------------------------------------------------------------

class Parser {
 public:
  Parser(std::string_view text, const std::string& name)
      : lex_(text, name), doing_(fmt::format("parsing '{}'", name)) {}

  Scene parse() {
    while (lex_.skip()) {
      poll_stop();
      const char* at = lex_.position();
      const std::string_view kw = lex_.take_token();
      entity_ = kw;
      if (kw == "p") {
        parse_polygon(false);
      } else if (kw == "pp") {
        parse_polygon(true);
      } else if (kw == "s") {
        parse_sphere();
      } else if (kw == "c") {
        parse_cone();
      } else if (kw == "f") {
        parse_material();
      } else if (kw == "l") {
        parse_light();
      } else if (kw == "b") {
        scene_.background = vec3("background colour");
      } else if (kw == "v") {
        parse_view();
      } else {
        float ignored = 0.0f;
        if (token_to_float(kw, ignored) != NumberStatus::kNotANumber) {
          lex_.fail_at(at, fmt::format("expected a keyword, found the number {} (too many numbers "
                                       "in the previous entity?)",
                                       quote(kw)));
        }
        lex_.fail_at(at, fmt::format("unknown keyword {}", quote(kw)));
      }
    }
    return std::move(scene_);
  }

 private:
  /// Polls the stop request every 4096 calls (entities and vertices).
  void poll_stop() {
    if ((++ticks_ & 4095u) == 0) throw_if_stopped(doing_);
  }

  [[noreturn]] void fail_truncated(const std::string& expected) {
    lex_.fail_at(lex_.end(), fmt::format("file ends inside a '{}' entity (expected {})", entity_,
                                         expected));
  }

  /// Reads one finite float; `what` names the field for messages. `missing`
  /// (when given) is the truncation wording, else `what` is used.
  float number(const char* what, const char* missing = nullptr) {
    if (!lex_.skip()) fail_truncated(missing ? missing : what);
    const char* at = lex_.position();
    const char* first = at;
    const char* last = lex_.end();
    float v = 0.0f;
    // Fast path: from_chars directly on the text, then check that the token
    // ended there. Anything unusual goes through token_to_float.
    if (*first != '+') {
      auto [ptr, ec] = std::from_chars(first, last, v);
      if (ec == std::errc{} && (ptr == last || is_delimiter(*ptr)) && std::isfinite(v)) {
        lex_.take_token();  // advances exactly to ptr
        return v;
      }
    }
    const std::string_view tok = lex_.take_token();
    switch (token_to_float(tok, v)) {
      case NumberStatus::kOk: return v;
      case NumberStatus::kNotFinite:
        lex_.fail_at(at, fmt::format("expected a finite number for {}, found {}", what, quote(tok)));
      case NumberStatus::kNotANumber: break;
    }
    lex_.fail_at(at, fmt::format("expected a number for {}, found {}", what, quote(tok)));
  }

  Vec3 vec3(const char* what, const char* missing = nullptr) {
    const float x = number(what, missing);
    const float y = number(what, missing);
    const float z = number(what, missing);
    return {x, y, z};
  }

  /// Reads an integer token; returns it with its position.
  std::pair<long long, const char*> integer(const char* what) {
    if (!lex_.skip()) fail_truncated(what);
    const char* at = lex_.position();
    const std::string_view tok = lex_.take_token();
    const char* first = tok.data();
    const char* last = first + tok.size();
    if (first != last && *first == '+') ++first;
    long long v = 0;
    auto [ptr, ec] = std::from_chars(first, last, v);
    if (ec == std::errc::result_out_of_range && ptr == last) {
      lex_.fail_at(at, fmt::format("{} {} is out of range", what, quote(tok)));
    }
    if (ec != std::errc{} || ptr != last) {
      lex_.fail_at(at, fmt::format("expected an integer for {}, found {}", what, quote(tok)));
    }
    return {v, at};
  }

  void parse_polygon(bool patch) {
    const char* noun = patch ? "patch" : "polygon";
    const auto [n, at] = integer(patch ? "patch vertex count" : "polygon vertex count");
    if (n < 3) {
      lex_.fail_at(at, fmt::format("{} has {} vertices; at least 3 are needed", noun, n));
    }
    if (n > kMaxPolygonVertices) {
      lex_.fail_at(at, fmt::format("{} has {} vertices; at most {} are supported", noun, n,
                                   kMaxPolygonVertices));
    }
    const auto count = static_cast<std::uint32_t>(n);
    // Grown per vertex (the scratch keeps its capacity), so a huge count in
    // a truncated file costs no more memory than the vertices present.
    verts_.clear();
    normals_.clear();
    for (std::uint32_t i = 0; i < count; ++i) {
      // Field and truncation wording are only formatted on the error path.
      const std::uint32_t left = count - i;
      poll_stop();
      try_vertex(patch, i, left);
    }
    if (is_degenerate_polygon(verts_.data(), count)) {
      ++scene_.dropped_degenerate;
      return;
    }
    // Ear clipping a concave polygon takes O(n^2) time: refused here, where
    // the file location is known (database.h).
    if (count > kMaxConcavePolygonVertices && !splits_in_linear_time(verts_.data(), count)) {
      lex_.fail_at(at, fmt::format("{} has {} vertices and is not convex; a concave {} may have at most {} "
                                   "vertices (triangulating one takes time quadratic in its vertices) unless it is "
                                   "star-shaped from its last vertex: split it",
                                   noun, n, noun, kMaxConcavePolygonVertices));
    }
    if (patch) {
      scene_.add_patch(verts_.data(), normals_.data(), count);
    } else {
      scene_.add_polygon(verts_.data(), count);
    }
  }

  /// Reads vertex i (and its normal for a patch); `left` vertices remain
  /// including this one.
  void try_vertex(bool patch, std::uint32_t i, std::uint32_t left) {
    // The common case: every token is a plain finite number.
    float v[6];
    const int k = patch ? 6 : 3;
    for (int j = 0; j < k; ++j) {
      if (!lex_.skip()) {
        fail_truncated(fmt::format("{} more vert{}", left, left == 1 ? "ex" : "ices"));
      }
      if (!fast_number(v[j])) {
        const std::string what =
            fmt::format("{} {} {}", patch ? "patch" : "polygon", j < 3 ? "vertex" : "normal", i + 1);
        v[j] = number(what.c_str());  // throws with the right message
      }
    }
    verts_.push_back({v[0], v[1], v[2]});
    if (patch) normals_.push_back({v[3], v[4], v[5]});
  }

  /// At a token start: converts a plain finite number and consumes it, or
  /// leaves the lexer unchanged and returns false.
  bool fast_number(float& out) {
    const char* first = lex_.position();
    if (*first == '+') return false;
    auto [ptr, ec] = std::from_chars(first, lex_.end(), out);
    if (ec != std::errc{} || (ptr != lex_.end() && !is_delimiter(*ptr)) || !std::isfinite(out)) {
      return false;
    }
    lex_.take_token();
    return true;
  }

  void parse_sphere() {
    Sphere s;
    s.center = vec3("sphere centre");
    s.radius = number("sphere radius");
    scene_.add_sphere(s);
  }

  void parse_cone() {
    Cone c;
    c.base = vec3("cone base centre");
    c.base_radius = number("cone base radius");
    c.apex = vec3("cone apex centre");
    c.apex_radius = number("cone apex radius");
    scene_.add_cone(c);
  }

  void parse_material() {
    Material m;
    m.color = vec3("material colour");
    m.kd = number("material Kd");
    m.ks = number("material Ks");
    m.shine = number("material Shine");
    m.transmittance = number("material T");
    m.ior = number("material ior");
    scene_.materials.push_back(m);
  }

  void parse_light() {
    Light l;
    l.position = vec3("light position");
    // The colour is optional: it is there when the next token is numeric
    // (including 'nan'/'inf', which are then reported as non-finite).
    const std::string_view next = lex_.peek_token();
    float ignored = 0.0f;
    if (!next.empty() && token_to_float(next, ignored) != NumberStatus::kNotANumber) {
      l.color = vec3("light colour");
      l.has_color = true;
    }
    scene_.lights.push_back(l);
  }

  void parse_view() {
    static constexpr std::array<std::string_view, 6> kLabels = {"from",  "at",     "up",
                                                                 "angle", "hither", "resolution"};
    View& v = scene_.view;
    bool seen[6] = {};
    const char* label_at[6] = {};  // where each label stands, for the checks below
    for (int done = 0; done < 6; ++done) {
      int missing = 0;
      while (seen[missing]) ++missing;
      const std::string expected = fmt::format("'{}'", kLabels[missing]);
      if (!lex_.skip()) fail_truncated(expected);
      const char* at = lex_.position();
      const std::string_view label = lex_.take_token();
      int which = -1;
      for (int i = 0; i < 6; ++i) {
        if (label == kLabels[i]) which = i;
      }
      if (which < 0) {
        lex_.fail_at(at, fmt::format("expected {} in the view block, found {}", expected,
                                     quote(label)));
      }
      if (seen[which]) {
        lex_.fail_at(at, fmt::format("'{}' appears twice in the view block", label));
      }
      seen[which] = true;
      label_at[which] = at;
      switch (which) {
        case 0: v.from = vec3("view 'from'"); break;
        case 1: v.at = vec3("view 'at'"); break;
        case 2: v.up = vec3("view 'up'"); break;
        case 3: v.angle = number("view 'angle'"); break;
        case 4: v.hither = number("view 'hither'"); break;
        case 5:
          v.width = resolution("resolution width");
          v.height = resolution("resolution height");
          break;
      }
    }
    check_view(v, label_at);
    scene_.has_view = true;
  }

  /// A view the camera can use (the same conditions as core::Camera, so a
  /// scene the reader accepts always renders): 'at' away from 'from', 'up'
  /// not parallel to the viewing direction, angle in (0, 180) degrees.
  /// Errors stand at the label of the offending field.
  void check_view(const View& v, const char* const label_at[6]) {
    auto text = [](const Vec3& p) { return fmt::format("({}, {}, {})", p.x, p.y, p.z); };
    const Vec3 dir = v.at - v.from;
    if (!is_finite(dir)) {
      lex_.fail_at(label_at[1], fmt::format("view 'at' {} is too far from 'from' {}: the viewing direction "
                                            "overflows float", text(v.at), text(v.from)));
    }
    if (!(dot(dir, dir) > 0.0f)) {
      lex_.fail_at(label_at[1], v.at == v.from
                                    ? fmt::format("view 'at' {} is the same point as 'from'", text(v.at))
                                    : fmt::format("view 'at' {} is too close to 'from' {} to give a viewing "
                                                  "direction", text(v.at), text(v.from)));
    }
    if (!(dot(v.up, v.up) > 0.0f)) {
      lex_.fail_at(label_at[2], fmt::format("view 'up' {} is parallel to the viewing direction {} (it has no "
                                            "length)", text(v.up), text(dir)));
    }
    if (!up_is_usable(normalize_any(dir), v.up)) {
      lex_.fail_at(label_at[2], fmt::format("view 'up' {} is parallel to the viewing direction {}", text(v.up),
                                            text(dir)));
    }
    if (!(v.angle > 0.0f && v.angle < 180.0f)) {
      lex_.fail_at(label_at[3], fmt::format("view 'angle' {} must be in (0, 180) degrees", v.angle));
    }
  }

  int resolution(const char* what) {
    const auto [n, at] = integer(what);
    if (n <= 0) {
      lex_.fail_at(at, fmt::format("{} must be a positive number of pixels, found {}", what, n));
    }
    if (n > kMaxResolution) {
      lex_.fail_at(at, fmt::format("{} {} is above the {} pixels supported", what, n, kMaxResolution));
    }
    return static_cast<int>(n);
  }

  Lexer lex_;
  const std::string doing_;     ///< "parsing '<name>'", for the stop request
  std::uint32_t ticks_ = 0;     ///< poll_stop() calls
  Scene scene_;
  std::string_view entity_;     ///< keyword of the entity being parsed
  std::vector<Vec3> verts_;     ///< scratch: current polygon's vertices
  std::vector<Vec3> normals_;   ///< scratch: current patch's normals
};

std::string errno_text(int err) { return std::strerror(err); }

// ---------------------------------------------------------------------------
// Writer
// ---------------------------------------------------------------------------

using Sink = std::function<void(const char*, std::size_t)>;

void write_nff_to(const Sink& sink, const Scene& scene) {
  constexpr std::size_t kFlushAt = std::size_t{1} << 18;
  fmt::memory_buffer buf;
  auto out = std::back_inserter(buf);
  auto flush = [&] {
    if (buf.size() != 0) sink(buf.data(), buf.size());
    buf.clear();
  };
  auto vec = [&](const Vec3& v) { fmt::format_to(out, "{} {} {}", v.x, v.y, v.z); };

  fmt::format_to(out, "b ");
  vec(scene.background);
  fmt::format_to(out, "\n");
  if (scene.has_view) {
    const View& v = scene.view;
    fmt::format_to(out, "v\nfrom ");
    vec(v.from);
    fmt::format_to(out, "\nat ");
    vec(v.at);
    fmt::format_to(out, "\nup ");
    vec(v.up);
    fmt::format_to(out, "\nangle {}\nhither {}\nresolution {} {}\n", v.angle, v.hither, v.width,
                   v.height);
  }
  for (const Light& l : scene.lights) {
    fmt::format_to(out, "l ");
    vec(l.position);
    if (l.has_color) {
      fmt::format_to(out, " ");
      vec(l.color);
    }
    fmt::format_to(out, "\n");
  }

  auto material = [&](std::size_t i) {
    const Material& m = scene.materials[i];
    fmt::format_to(out, "f ");
    vec(m.color);
    fmt::format_to(out, " {} {} {} {} {}\n", m.kd, m.ks, m.shine, m.transmittance, m.ior);
  };
  // `emitted` materials have been written; `current` is the one in force.
  std::size_t emitted = 0;
  std::size_t current = std::numeric_limits<std::size_t>::max();
  for (std::size_t si = 0; si < scene.shapes.size(); ++si) {
    const Shape& s = scene.shapes[si];
    if (s.material >= scene.materials.size()) {
      throw std::runtime_error(fmt::format("write_nff: shape {} uses material {} but the scene "
                                           "has {} materials",
                                           si, s.material, scene.materials.size()));
    }
    if (s.material != current) {
      if (s.material >= emitted) {
        while (emitted <= s.material) material(emitted++);
      } else {
        // A shape going back to an earlier material (never produced by the
        // reader): restate it. Appearance survives; the materials list of the
        // re-read scene gains a copy.
        material(s.material);
      }
      current = s.material;
    }
    switch (s.kind) {
      case ShapeKind::kPolygon:
        fmt::format_to(out, "p {}\n", s.count);
        for (std::uint32_t i = 0; i < s.count; ++i) {
          vec(scene.vertices[s.first + i]);
          fmt::format_to(out, "\n");
        }
        break;
      case ShapeKind::kPatch:
        fmt::format_to(out, "pp {}\n", s.count);
        for (std::uint32_t i = 0; i < s.count; ++i) {
          vec(scene.vertices[s.first + i]);
          fmt::format_to(out, " ");
          vec(scene.normals[s.first_normal + i]);
          fmt::format_to(out, "\n");
        }
        break;
      case ShapeKind::kSphere: {
        const Sphere& sp = scene.spheres[s.first];
        fmt::format_to(out, "s ");
        vec(sp.center);
        fmt::format_to(out, " {}\n", sp.radius);
        break;
      }
      case ShapeKind::kCone: {
        const Cone& c = scene.cones[s.first];
        fmt::format_to(out, "c ");
        vec(c.base);
        fmt::format_to(out, " {} ", c.base_radius);
        vec(c.apex);
        fmt::format_to(out, " {}\n", c.apex_radius);
        break;
      }
    }
    if (buf.size() >= kFlushAt) flush();
  }
  // Materials no shape uses (after the last shape) still round-trip.
  while (emitted < scene.materials.size()) material(emitted++);
  flush();
}

bool ends_with(std::string_view s, std::string_view suffix) {
  return s.size() >= suffix.size() && s.substr(s.size() - suffix.size()) == suffix;
}

}  // namespace

Scene parse_nff(std::string_view text, const std::string& name) {
  return Parser(text, name).parse();
}

Scene read_nff(const std::string& path) {
  const std::string data = read_scene_text(path);
  return parse_nff(data, path);
}

void write_nff(std::ostream& out, const Scene& scene) {
  write_nff_to(
      [&out](const char* p, std::size_t n) { out.write(p, static_cast<std::streamsize>(n)); },
      scene);
}

void write_nff_into(const std::string& file_path, const Scene& scene, bool gzip, const std::string& name) {
  const std::string& tmp = file_path;
  auto fail = [&](const std::string& why) {
    throw std::runtime_error(fmt::format("cannot write '{}': {}", name, why));
  };
  if (gzip) {
    gzFile gz = gzopen(tmp.c_str(), "wb");
    if (!gz) fail(errno ? errno_text(errno) : "gzopen failed");
    std::string error;
    try {
      write_nff_to(
          [&](const char* p, std::size_t n) {
            while (n > 0) {
              const unsigned step = static_cast<unsigned>(std::min<std::size_t>(n, 1u << 30));
              if (gzwrite(gz, p, step) != static_cast<int>(step)) {
                int errnum = 0;
                const char* msg = gzerror(gz, &errnum);
                throw std::runtime_error(errnum == Z_ERRNO ? errno_text(errno) : msg);
              }
              p += step;
              n -= step;
            }
          },
          scene);
    } catch (const std::exception& e) {
      error = e.what();
    }
    const int rc = gzclose(gz);
    if (error.empty() && rc != Z_OK) error = rc == Z_ERRNO ? errno_text(errno) : "gzclose failed";
    if (!error.empty()) fail(error);
  } else {
    std::FILE* f = std::fopen(tmp.c_str(), "wb");
    if (!f) fail(errno_text(errno));
    std::string error;
    try {
      write_nff_to(
          [&](const char* p, std::size_t n) {
            if (std::fwrite(p, 1, n, f) != n) throw std::runtime_error(errno_text(errno));
          },
          scene);
    } catch (const std::exception& e) {
      error = e.what();
    }
    if (std::fclose(f) != 0 && error.empty()) error = errno_text(errno);
    if (!error.empty()) fail(error);
  }
}

void write_nff_file(const std::string& path, const Scene& scene) {
  const std::string tmp = path + ".tmp";
  try {
    write_nff_into(tmp, scene, ends_with(path, ".gz"), path);
  } catch (...) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw;
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw std::runtime_error(fmt::format("cannot write '{}': {}", path, ec.message()));
  }
}

}  // namespace raynode::core
