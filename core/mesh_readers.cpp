// PLY and OFF readers. See mesh_readers.h.
#include "core/mesh_readers.h"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <optional>
#include <stdexcept>

#include <fmt/format.h>

#include "core/stop.h"

namespace raynode::core {

namespace {

constexpr std::size_t kStopCheckItems = 1 << 16;

[[noreturn]] void fail(const std::string& path, const std::string& why) {
  throw std::runtime_error(fmt::format("cannot read mesh '{}': {}", path, why));
}

/// Whitespace-separated tokens of text, with the 1-based line of the last one.
class Tokens {
 public:
  explicit Tokens(std::string_view text, bool hash_comments = false) : t_(text), comments_(hash_comments) {}
  /// The next token, or an empty view at the end of the text.
  std::string_view next() {
    for (;;) {
      while (pos_ < t_.size() && std::isspace(static_cast<unsigned char>(t_[pos_]))) {
        if (t_[pos_] == '\n') ++line_;
        ++pos_;
      }
      if (comments_ && pos_ < t_.size() && t_[pos_] == '#') {
        while (pos_ < t_.size() && t_[pos_] != '\n') ++pos_;
        continue;
      }
      break;
    }
    const std::size_t start = pos_;
    while (pos_ < t_.size() && !std::isspace(static_cast<unsigned char>(t_[pos_]))) ++pos_;
    return t_.substr(start, pos_ - start);
  }
  /// The rest of the current line (for skipping colours), consumed.
  void skip_line() {
    while (pos_ < t_.size() && t_[pos_] != '\n') ++pos_;
  }
  int line() const { return line_; }
  std::size_t pos() const { return pos_; }

 private:
  std::string_view t_;
  bool comments_;
  std::size_t pos_ = 0;
  int line_ = 1;
};

std::optional<double> to_double(std::string_view s) {
  double v = 0;
  const char* b = s.data();
  if (!s.empty() && *b == '+') ++b;
  const auto [end, ec] = std::from_chars(b, s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size()) return std::nullopt;
  return v;
}

std::optional<long long> to_int(std::string_view s) {
  long long v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size()) return std::nullopt;
  return v;
}

// ---- PLY ------------------------------------------------------------------

enum class PlyType : std::uint8_t { kI8, kU8, kI16, kU16, kI32, kU32, kF32, kF64 };

std::optional<PlyType> ply_type(std::string_view s) {
  if (s == "char" || s == "int8") return PlyType::kI8;
  if (s == "uchar" || s == "uint8") return PlyType::kU8;
  if (s == "short" || s == "int16") return PlyType::kI16;
  if (s == "ushort" || s == "uint16") return PlyType::kU16;
  if (s == "int" || s == "int32") return PlyType::kI32;
  if (s == "uint" || s == "uint32") return PlyType::kU32;
  if (s == "float" || s == "float32") return PlyType::kF32;
  if (s == "double" || s == "float64") return PlyType::kF64;
  return std::nullopt;
}

std::size_t ply_size(PlyType t) {
  switch (t) {
    case PlyType::kI8: case PlyType::kU8: return 1;
    case PlyType::kI16: case PlyType::kU16: return 2;
    case PlyType::kI32: case PlyType::kU32: case PlyType::kF32: return 4;
    case PlyType::kF64: return 8;
  }
  return 1;
}

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::kF32;
  bool list = false;
  PlyType count_type = PlyType::kU8;
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> props;
};

/// Reads binary values with bounds checks, in the file's byte order.
class BinaryReader {
 public:
  BinaryReader(std::string_view data, std::size_t pos, bool big_endian, const std::string& path)
      : d_(data), pos_(pos), swap_(big_endian != (std::endian::native == std::endian::big)), path_(path) {}

  double read(PlyType t, const char* what, std::uint64_t item) {
    const std::size_t n = ply_size(t);
    if (d_.size() - pos_ < n)
      fail(path_, fmt::format("the file ends at byte {} inside {} {} (truncated)", d_.size(), what, item));
    unsigned char b[8];
    std::memcpy(b, d_.data() + pos_, n);
    pos_ += n;
    if (swap_) std::reverse(b, b + n);
    switch (t) {
      case PlyType::kI8: { std::int8_t v; std::memcpy(&v, b, 1); return v; }
      case PlyType::kU8: return b[0];
      case PlyType::kI16: { std::int16_t v; std::memcpy(&v, b, 2); return v; }
      case PlyType::kU16: { std::uint16_t v; std::memcpy(&v, b, 2); return v; }
      case PlyType::kI32: { std::int32_t v; std::memcpy(&v, b, 4); return v; }
      case PlyType::kU32: { std::uint32_t v; std::memcpy(&v, b, 4); return v; }
      case PlyType::kF32: { float v; std::memcpy(&v, b, 4); return v; }
      case PlyType::kF64: { double v; std::memcpy(&v, b, 8); return v; }
    }
    return 0;
  }

 private:
  std::string_view d_;
  std::size_t pos_;
  bool swap_;
  const std::string& path_;
};

}  // namespace

MeshData read_ply(std::string_view bytes, const std::string& path) {
  // Header: lines up to "end_header".
  std::size_t pos = 0;
  int line_no = 0;
  auto next_line = [&]() -> std::optional<std::string_view> {
    if (pos >= bytes.size()) return std::nullopt;
    const std::size_t nl = bytes.find('\n', pos);
    const std::size_t end = nl == std::string_view::npos ? bytes.size() : nl;
    std::string_view l = bytes.substr(pos, end - pos);
    pos = nl == std::string_view::npos ? bytes.size() : nl + 1;
    ++line_no;
    if (!l.empty() && l.back() == '\r') l.remove_suffix(1);
    return l;
  };
  auto header_fail = [&](const std::string& why) { fail(path, fmt::format("header line {}: {}", line_no, why)); };
  const auto magic = next_line();
  if (!magic || (*magic != "ply" && *magic != "PLY")) header_fail("expected 'ply'");
  enum class Format { kAscii, kLittle, kBig } format = Format::kAscii;
  bool have_format = false, ended = false;
  std::vector<PlyElement> elements;
  while (const auto l = next_line()) {
    Tokens tk(*l);
    const std::string_view key = tk.next();
    if (key.empty() || key == "comment" || key == "obj_info") continue;
    if (key == "end_header") {
      ended = true;
      break;
    }
    if (key == "format") {
      const std::string_view f = tk.next();
      if (f == "ascii") format = Format::kAscii;
      else if (f == "binary_little_endian") format = Format::kLittle;
      else if (f == "binary_big_endian") format = Format::kBig;
      else header_fail(fmt::format("unknown format '{}'", f));
      have_format = true;
    } else if (key == "element") {
      PlyElement e;
      e.name = std::string(tk.next());
      const auto n = to_int(tk.next());
      if (e.name.empty() || !n || *n < 0) header_fail("expected 'element NAME COUNT'");
      e.count = std::uint64_t(*n);
      elements.push_back(std::move(e));
    } else if (key == "property") {
      if (elements.empty()) header_fail("a property before any element");
      PlyProperty p;
      std::string_view t = tk.next();
      if (t == "list") {
        p.list = true;
        const auto ct = ply_type(tk.next());
        if (!ct || *ct == PlyType::kF32 || *ct == PlyType::kF64) header_fail("bad list count type");
        p.count_type = *ct;
        t = tk.next();
      }
      const auto ty = ply_type(t);
      if (!ty) header_fail(fmt::format("unknown property type '{}'", t));
      p.type = *ty;
      p.name = std::string(tk.next());
      if (p.name.empty()) header_fail("a property without a name");
      elements.back().props.push_back(std::move(p));
    } else {
      header_fail(fmt::format("unknown keyword '{}'", key));
    }
  }
  if (!ended) fail(path, "the header has no 'end_header' (truncated)");
  if (!have_format) fail(path, "the header has no 'format' line");

  MeshData m;
  const std::string doing = fmt::format("reading mesh '{}'", path);
  Tokens text(bytes.substr(pos));
  BinaryReader bin(bytes, pos, format == Format::kBig, path);
  // One value of the body, by type.
  auto value = [&](PlyType t, const char* what, std::uint64_t item) -> double {
    if (format != Format::kAscii) return bin.read(t, what, item);
    const std::string_view tok = text.next();
    if (tok.empty()) fail(path, fmt::format("the file ends inside {} {} (truncated)", what, item));
    const auto v = to_double(tok);
    if (!v) fail(path, fmt::format("{} {}: '{}' is not a number", what, item, tok));
    return *v;
  };
  std::uint64_t vertex_count = 0;
  for (const PlyElement& e : elements) {
    if (e.props.size() > 64 && (e.name == "vertex" || e.name == "face"))
      fail(path, fmt::format("the {} element has {} properties, more than 64", e.name, e.props.size()));
    const bool is_vertex = e.name == "vertex", is_face = e.name == "face";
    int x = -1, y = -1, z = -1, nx = -1, ny = -1, nz = -1, list = -1;
    for (int i = 0; i < int(e.props.size()); ++i) {
      const PlyProperty& p = e.props[i];
      if (p.list) {
        if (is_face && (p.name == "vertex_indices" || p.name == "vertex_index")) list = i;
        continue;
      }
      if (p.name == "x") x = i;
      else if (p.name == "y") y = i;
      else if (p.name == "z") z = i;
      else if (p.name == "nx") nx = i;
      else if (p.name == "ny") ny = i;
      else if (p.name == "nz") nz = i;
    }
    if (is_vertex) {
      if (x < 0 || y < 0 || z < 0) fail(path, "the vertex element has no x, y and z properties");
      if (e.count > std::uint64_t(UINT32_MAX) || e.count > bytes.size())
        fail(path, fmt::format("{} vertices announced in a {}-byte file", e.count, bytes.size()));
      vertex_count = e.count;
      m.positions.reserve(e.count);
      if (nx >= 0 && ny >= 0 && nz >= 0) m.normals.reserve(e.count);
    }
    if (is_face && e.count > bytes.size())
      fail(path, fmt::format("{} faces announced in a {}-byte file", e.count, bytes.size()));
    if (is_face) {
      m.face_sizes.reserve(e.count);
      m.face_indices.reserve(e.count * 3);
    }
    const bool want_normals = is_vertex && nx >= 0 && ny >= 0 && nz >= 0;
    double val[64];
    for (std::uint64_t item = 0; item < e.count; ++item) {
      if ((item + 1) % kStopCheckItems == 0) throw_if_stopped(doing);
      for (int i = 0; i < int(e.props.size()); ++i) {
        const PlyProperty& p = e.props[i];
        if (!p.list) {
          const double v = value(p.type, e.name.c_str(), item);
          if (i < 64) val[i] = v;
          continue;
        }
        const double n = value(p.count_type, e.name.c_str(), item);
        if (!(n >= 0) || n > 1e6) fail(path, fmt::format("{} {}: a list of {} values", e.name, item, n));
        const auto count = std::uint32_t(n);
        if (i == list) m.face_sizes.push_back(count);
        for (std::uint32_t k = 0; k < count; ++k) {
          const double v = value(p.type, e.name.c_str(), item);
          if (i != list) continue;
          if (!(v >= 0 && v < double(vertex_count)))
            fail(path, fmt::format("face {} refers to vertex {}, but there are {} vertices", item, v, vertex_count));
          m.face_indices.push_back(std::uint32_t(v));
        }
      }
      if (is_vertex) {
        const Vec3 p{float(val[x]), float(val[y]), float(val[z])};
        if (!is_finite(p))
          fail(path, fmt::format("vertex {} ({}, {}, {}) is not finite", item, val[x], val[y], val[z]));
        m.positions.push_back(p);
        if (want_normals) m.normals.push_back({float(val[nx]), float(val[ny]), float(val[nz])});
      } else if (is_face && list < 0) {
        fail(path, "the face element has no vertex_indices list");
      }
    }
  }
  return m;
}

// ---- OFF ------------------------------------------------------------------

MeshData read_off(std::string_view bytes, const std::string& path) {
  Tokens tk(bytes, true);
  auto where = [&] { return fmt::format("line {}", tk.line()); };
  const std::string_view magic = tk.next();
  if (magic.size() < 3 || magic.substr(magic.size() - 3) != "OFF")
    fail(path, fmt::format("line 1: expected 'OFF', found '{}'", magic.substr(0, 40)));
  const bool has_normals = magic.find('N') != std::string_view::npos;
  const bool has_colours = magic.find('C') != std::string_view::npos;
  auto integer = [&](const char* what) {
    const std::string_view t = tk.next();
    if (t.empty()) fail(path, fmt::format("{}: the file ends before the {} (truncated)", where(), what));
    const auto v = to_int(t);
    if (!v || *v < 0) fail(path, fmt::format("{}: expected the {}, found '{}'", where(), what, t.substr(0, 40)));
    return *v;
  };
  auto number = [&](const char* what, long long item) {
    const std::string_view t = tk.next();
    if (t.empty()) fail(path, fmt::format("{}: the file ends inside {} {} (truncated)", where(), what, item));
    const auto v = to_double(t);
    if (!v || !std::isfinite(*v))
      fail(path, fmt::format("{}: {} {}: expected a finite number, found '{}'", where(), what, item, t.substr(0, 40)));
    return float(*v);
  };
  const long long nv = integer("vertex count"), nf = integer("face count");
  integer("edge count");
  if (std::uint64_t(nv) > bytes.size() || std::uint64_t(nf) > bytes.size())
    fail(path, fmt::format("{} vertices and {} faces announced in a {}-byte file", nv, nf, bytes.size()));
  MeshData m;
  m.positions.reserve(std::size_t(nv));
  const std::string doing = fmt::format("reading mesh '{}'", path);
  for (long long i = 0; i < nv; ++i) {
    if ((i + 1) % kStopCheckItems == 0) throw_if_stopped(doing);
    const float x = number("vertex", i), y = number("vertex", i), z = number("vertex", i);
    m.positions.push_back({x, y, z});
    if (has_normals) {
      const float a = number("vertex normal", i), b = number("vertex normal", i), c = number("vertex normal", i);
      m.normals.push_back({a, b, c});
    }
    if (has_colours) tk.skip_line();
  }
  for (long long f = 0; f < nf; ++f) {
    if ((f + 1) % kStopCheckItems == 0) throw_if_stopped(doing);
    const long long n = integer("face's vertex count");
    if (n > 1000000) fail(path, fmt::format("{}: face {} has {} vertices", where(), f, n));
    m.face_sizes.push_back(std::uint32_t(n));
    for (long long k = 0; k < n; ++k) {
      const long long idx = integer("vertex index");
      if (idx >= nv)
        fail(path, fmt::format("{}: face {} refers to vertex {}, but there are {} vertices", where(), f, idx, nv));
      m.face_indices.push_back(std::uint32_t(idx));
    }
    tk.skip_line();  // an optional colour
  }
  return m;
}

}  // namespace raynode::core
