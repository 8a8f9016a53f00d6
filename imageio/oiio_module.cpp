// The OpenImageIO side of imageio (write_image.cpp), built as a module that
// the program loads with dlopen only when it reads or writes an image file.
//
// Why a module: OpenImageIO pulls in ~260 shared libraries (codecs, DICOM,
// video), and resolving their symbols at start-up took ~0.3 s of every
// raynode command, `--version` and `scene info` included. Loaded on demand,
// only the commands that write an image pay it.
//
// C interface (the loader looks these names up; see write_image.cpp):
//   int raynode_oiio_can_write(const char* path)
//       1 when OpenImageIO has a writer for path's extension, else 0.
//   int raynode_oiio_write(const char* format_path, const char* path, int width, int height,
//                          int channels, int is_float, const void* pixels, char* error, unsigned error_size)
//       Writes width x height x channels values, row-major, float (is_float)
//       or 8-bit, to `path` in the format `format_path`'s extension names.
//       Returns 1, or 0 with OpenImageIO's message in `error` (NUL-terminated,
//       truncated to error_size).
#include <OpenImageIO/imageio.h>

#include <cstring>
#include <string>

namespace {

void set_error(char* error, unsigned size, const std::string& message) {
  if (size == 0) return;
  const std::size_t n = std::min<std::size_t>(message.size(), size - 1);
  std::memcpy(error, message.data(), n);
  error[n] = '\0';
}

}  // namespace

extern "C" __attribute__((visibility("default"))) int raynode_oiio_can_write(const char* path) {
  auto out = OIIO::ImageOutput::create(path);
  if (!out) OIIO::geterror();  // clear the pending message
  return out ? 1 : 0;
}

extern "C" __attribute__((visibility("default"))) int raynode_oiio_write(const char* format_path, const char* path,
                                                                        int width, int height, int channels,
                                                                        int is_float, const void* pixels,
                                                                        char* error, unsigned error_size) {
  // The plugin is chosen from the final name (`path` may be a temporary).
  auto out = OIIO::ImageOutput::create(format_path);
  if (!out) {
    set_error(error, error_size, "cannot write this format: " + OIIO::geterror());
    return 0;
  }
  const OIIO::TypeDesc type = is_float ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8;
  const OIIO::ImageSpec spec(width, height, channels, type);
  if (!out->open(path, spec)) {
    set_error(error, error_size, out->geterror());
    return 0;
  }
  if (!out->write_image(type, pixels)) {
    set_error(error, error_size, out->geterror());
    out->close();
    return 0;
  }
  if (!out->close()) {
    set_error(error, error_size, out->geterror());
    return 0;
  }
  return 1;
}
