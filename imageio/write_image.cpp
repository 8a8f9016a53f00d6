#include "imageio/write_image.h"

#include <OpenImageIO/imageio.h>
#include <fmt/core.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
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

}  // namespace

bool is_float_format(const std::string& path) {
  const std::string ext = lower_extension(path);
  return ext == ".exr" || ext == ".hdr";
}

bool can_write_format(const std::string& path) {
  auto out = OIIO::ImageOutput::create(path);
  if (!out) OIIO::geterror();  // clear the pending message
  return bool(out);
}

void write_image(const std::string& path, const core::Image& image) {
  namespace fs = std::filesystem;
  if (image.width < 1 || image.height < 1 || image.channels < 1 ||
      image.pixels.size() != std::size_t(image.width) * image.height * image.channels)
    throw std::runtime_error(fmt::format("{}: image has inconsistent size {}x{}x{} ({} floats)", path, image.width,
                                         image.height, image.channels, image.pixels.size()));
  // The plugin is chosen from the final name; the temporary keeps the extension too.
  auto out = OIIO::ImageOutput::create(path);
  if (!out) throw std::runtime_error(fmt::format("{}: cannot write this format: {}", path, OIIO::geterror()));
  const fs::path final_path(path);
  const fs::path tmp = final_path.parent_path() /
                       fmt::format(".{}.tmp{}{}", final_path.stem().string(), ::getpid(), final_path.extension().string());
  const bool as_float = is_float_format(path);
  OIIO::ImageSpec spec(image.width, image.height, image.channels, as_float ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8);
  auto fail = [&](const std::string& what) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw std::runtime_error(fmt::format("{}: {}", path, what));
  };
  if (!out->open(tmp.string(), spec)) fail(out->geterror());
  bool ok;
  if (as_float) {
    ok = out->write_image(OIIO::TypeDesc::FLOAT, image.pixels.data());
  } else {
    std::vector<std::uint8_t> bytes(image.pixels.size());
    for (std::size_t i = 0; i < bytes.size(); ++i) {
      float v = image.pixels[i];
      v = std::isnan(v) ? 0.0f : std::clamp(v, 0.0f, 1.0f);
      bytes[i] = static_cast<std::uint8_t>(std::lround(v * 255.0f));
    }
    ok = out->write_image(OIIO::TypeDesc::UINT8, bytes.data());
  }
  if (!ok) {
    const std::string err = out->geterror();
    out->close();
    fail(err);
  }
  if (!out->close()) fail(out->geterror());
  out.reset();
  std::error_code ec;
  fs::rename(tmp, final_path, ec);
  if (ec) fail("cannot rename the temporary file into place: " + ec.message());
}

}  // namespace raynode::imageio
