#include "imageio/write_image.h"

#include <dlfcn.h>
#include <fmt/core.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <system_error>
#include <vector>

namespace raynode::imageio {

namespace {

std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

/// The OpenImageIO module's entry points (oiio_module.cpp), loaded once.
struct OiioModule {
  int (*can_write)(const char* path) = nullptr;
  int (*write)(const char* format_path, const char* path, int width, int height, int channels, int is_float,
               const void* pixels, char* error, unsigned error_size) = nullptr;
};

/// Loads the module from beside the executable (the build tree), else from
/// the installed layout relative to the executable (bin/../lib/raynode,
/// RAYNODE_OIIO_MODULE_INSTALLED), else from the build tree it was built in
/// (RAYNODE_OIIO_MODULE_PATH: test programs live elsewhere in that tree).
/// Throws std::runtime_error naming the places tried and dlopen's message.
const OiioModule& oiio() {
  static OiioModule module;
  static std::string failure;
  static std::once_flag once;
  std::call_once(once, [] {
    namespace fs = std::filesystem;
    std::vector<std::string> places;
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (!ec) {
      places.push_back((exe.parent_path() / RAYNODE_OIIO_MODULE_NAME).string());
      places.push_back((exe.parent_path() / RAYNODE_OIIO_MODULE_INSTALLED / RAYNODE_OIIO_MODULE_NAME).lexically_normal().string());
    }
    places.push_back(RAYNODE_OIIO_MODULE_PATH);
    std::string errors;
    for (const std::string& place : places) {
      void* handle = ::dlopen(place.c_str(), RTLD_NOW | RTLD_LOCAL);
      if (!handle) {
        errors += fmt::format("\n  {}: {}", place, ::dlerror());
        continue;
      }
      module.can_write = reinterpret_cast<decltype(module.can_write)>(::dlsym(handle, "raynode_oiio_can_write"));
      module.write = reinterpret_cast<decltype(module.write)>(::dlsym(handle, "raynode_oiio_write"));
      if (module.can_write && module.write) return;  // kept loaded for the process's life
      errors += fmt::format("\n  {}: not raynode's OpenImageIO module (entry points missing)", place);
    }
    failure = "cannot load the image writer (raynode's OpenImageIO module); tried:" + errors;
  });
  if (!module.write) throw std::runtime_error(failure);
  return module;
}

}  // namespace

bool is_float_format(const std::string& path) {
  const std::string ext = lower_extension(path);
  return ext == ".exr" || ext == ".hdr";
}

bool can_write_format(const std::string& path) { return oiio().can_write(path.c_str()) != 0; }

void write_image_as(const std::string& format_path, const std::string& file_path, const core::Image& image) {
  const std::string& path = format_path;
  if (image.width < 1 || image.height < 1 || image.channels < 1 ||
      image.pixels.size() != std::size_t(image.width) * image.height * image.channels)
    throw std::runtime_error(fmt::format("{}: image has inconsistent size {}x{}x{} ({} floats)", path, image.width,
                                         image.height, image.channels, image.pixels.size()));
  const OiioModule& io = oiio();
  const bool as_float = is_float_format(path);
  std::vector<std::uint8_t> bytes;
  if (!as_float) {
    bytes.resize(image.pixels.size());
    for (std::size_t i = 0; i < bytes.size(); ++i) {
      float v = image.pixels[i];
      v = std::isnan(v) ? 0.0f : std::clamp(v, 0.0f, 1.0f);
      bytes[i] = static_cast<std::uint8_t>(std::lround(v * 255.0f));
    }
  }
  const void* pixels = as_float ? static_cast<const void*>(image.pixels.data()) : bytes.data();
  char error[512] = "";
  if (!io.write(path.c_str(), file_path.c_str(), image.width, image.height, image.channels, as_float ? 1 : 0,
                pixels, error, sizeof error))
    throw std::runtime_error(fmt::format("{}: {}", path, error));
}

}  // namespace raynode::imageio
