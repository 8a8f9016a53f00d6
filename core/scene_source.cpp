#include "core/scene_source.h"

#include <cstdio>
#include <filesystem>
#include <stdexcept>

#include "core/mesh_file.h"
#include "core/nff.h"
#include "core/spd.h"

namespace raynode::core {

bool is_scene_file(const std::string& spec) {
  auto ends_with = [&](const char* s) {
    const std::string suf(s);
    return spec.size() >= suf.size() && spec.compare(spec.size() - suf.size(), suf.size(), suf) == 0;
  };
  std::error_code ec;
  // Any existing file but a directory: a FIFO or a device is read as NFF too.
  const auto st = std::filesystem::status(spec, ec);
  return ends_with(".nff") || ends_with(".nff.gz") || ends_with(".gz") || is_mesh_extension(spec) ||
         spec.find('/') != std::string::npos ||
         (!ec && std::filesystem::exists(st) && !std::filesystem::is_directory(st));
}

Scene load_scene(const SceneSource& source) {
  if (source.tessellate < 0 || source.tessellate > 1000)
    throw std::invalid_argument("--tessellate must be between 0 and 1000, got " +
                                std::to_string(source.tessellate));
  Scene s;
  if (is_scene_file(source.spec)) {
    if (is_mesh_file(source.spec)) {
      std::vector<std::string> notes;
      s = read_mesh(source.spec, &notes, source.view);
      for (const std::string& line : notes) std::fprintf(stderr, "raynode: %s\n", line.c_str());
    } else {
      s = read_nff(source.spec);
    }
    if (source.tessellate > 0) tessellate_scene(s, source.tessellate);
  } else {
    SpdParams p = parse_spd_spec(source.spec);
    p.tessellate = source.tessellate;
    s = make_spd_scene(p);
  }
  apply_view_override(s, source.view);
  if (source.floor != 0) add_stadium_floor(s, source.floor);
  transform_scene(s, source.eye_origin ? eye_at_origin_after(s, source.transform) : source.transform);
  return s;
}

}  // namespace raynode::core
