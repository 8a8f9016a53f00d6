// Built-in SPD generators: names, "name[:size]" parsing and dispatch.
// The generators themselves live in spd_<name>.cpp (spd_generators.h); the
// -t polygonalisation in tessellate.cpp.
#include "core/spd.h"

#include <charconv>
#include <stdexcept>
#include <string>

#include "core/spd_generators.h"

namespace raynode::core {
namespace {

struct Generator {
  const char* name;
  int default_size;  // the SPD program's own default size factor
  Scene (*make)(int size);
  // For -t R when tessellate_scene's world-space tessellation would differ
  // from SPD's (primitives written through a transform); null otherwise.
  Scene (*make_tessellated)(int size, int resolution) = nullptr;
};

// The original five in the order SPD 3.14 lists them, then the rest of its
// generators.
constexpr Generator kGenerators[] = {
    {"teapot", 6, spd::make_teapot},
    {"mount", 6, spd::make_mount},
    {"rings", 7, spd::make_rings},
    {"tetra", 6, spd::make_tetra},
    {"balls", 4, spd::make_balls},
    {"gears", 4, spd::make_gears},
    {"tree", 11, spd::make_tree},
    {"lattice", 12, spd::make_lattice},
    {"shells", 5, spd::make_shells},
    {"jacks", 1, spd::make_jacks, spd::make_jacks_tessellated},
    {"sombrero", 1, spd::make_sombrero},
};

const Generator* find_generator(std::string_view name) {
  for (const Generator& g : kGenerators) {
    if (name == g.name) return &g;
  }
  return nullptr;
}

std::string valid_names() {
  std::string out;
  for (const Generator& g : kGenerators) {
    if (!out.empty()) out += ", ";
    out += g.name;
  }
  return out;
}

[[noreturn]] void throw_unknown(std::string_view name) {
  throw std::invalid_argument("unknown SPD scene '" + std::string(name) +
                              "' (valid: " + valid_names() + ")");
}

}  // namespace

namespace spd {

void check_spd_size(const char* name, int size, int min_size, int max_size) {
  if (size < min_size || size > max_size) {
    throw std::invalid_argument(std::string(name) + ": size " + std::to_string(size) +
                                " is out of range " + std::to_string(min_size) + ".." +
                                std::to_string(max_size));
  }
}

}  // namespace spd

std::vector<std::string> spd_names() {
  std::vector<std::string> out;
  for (const Generator& g : kGenerators) out.emplace_back(g.name);
  return out;
}

SpdParams parse_spd_spec(std::string_view spec) {
  const std::size_t colon = spec.find(':');
  const std::string_view name = spec.substr(0, colon);
  if (!find_generator(name)) throw_unknown(name);
  SpdParams params;
  params.name = std::string(name);
  if (colon == std::string_view::npos) return params;

  const std::string_view size_text = spec.substr(colon + 1);
  int size = 0;
  const char* first = size_text.data();
  const char* last = first + size_text.size();
  const auto [end, ec] = std::from_chars(first, last, size);
  if (size_text.empty() || ec != std::errc{} || end != last || size < 1) {
    throw std::invalid_argument("bad size '" + std::string(size_text) + "' in SPD spec '" +
                                std::string(spec) + "': expected a positive integer");
  }
  params.size = size;
  return params;
}

Scene make_spd_scene(const SpdParams& params) {
  const Generator* g = find_generator(params.name);
  if (!g) throw_unknown(params.name);
  if (params.tessellate < 0) {
    throw std::invalid_argument("SPD tessellation " + std::to_string(params.tessellate) +
                                " must be 0 (curved) or at least 1");
  }
  const int size = params.size == -1 ? g->default_size : params.size;
  if (params.tessellate > 0 && g->make_tessellated) return g->make_tessellated(size, params.tessellate);
  Scene scene = g->make(size);
  if (params.tessellate > 0) tessellate_scene(scene, params.tessellate);
  return scene;
}

}  // namespace raynode::core
