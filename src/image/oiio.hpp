// Private to the library: the OpenImageIO image module (libnmbake_oiio.so).
//
// OpenImageIO links about 260 shared libraries (codecs, DICOM, video, ...),
// and resolving them costs ~0.2 s at every process start, more than the
// encode and write stages of a 2048^2 bake together. So the code that needs
// it (the TIFF, PIZ EXR and TGA writers, every reader) is built as a separate module that
// image.cpp loads with dlopen() on first use; a bake that writes PNG (the
// default) or EXR never loads it. The module is built by the same build as the
// library, so C++ types cross the boundary; kAbiVersion guards a stale file.
#pragma once

#include <cstddef>
#include <string>

#include "nmbake/image.hpp"

namespace nmbake::oiio_module {

constexpr int kAbiVersion = 4;
constexpr const char* kFileName = "libnmbake_oiio.so";
constexpr const char* kEntryPoint = "nmbake_oiio_module_api";

enum class Outcome : int { ok = 0, io_error = 1, bad_input = 2 };

struct Api {
  int abi_version;
  const char* oiio_version;  // the OpenImageIO library it runs with, "2.4.7"
  // Writes `image` (already checked: sized, finite) to `file` in `format`
  // (tiff16, exr_float_piz, tga8), the same bytes for the same pixels;
  // `dither`: 8-bit samples (tga8) with ordered dithering (quantise.hpp).
  Outcome (*write)(const Image& image, const std::string& file, PixelFormat format, bool dither,
                   std::string& reason);
  // `reader` is the OpenImageIO format name image.cpp picked from the file's
  // first bytes ("png", "openexr", ...): only that reader sees the file.
  // `bytes` non-null: the file is those `size` bytes in memory (read through
  // Filesystem::IOMemReader; `path` only names it), not the file `path`.
  Outcome (*read_info)(const std::string& path, const std::string& reader, const unsigned char* bytes,
                       std::size_t size, ImageFileInfo& out, std::string& reason);
  // Float pixels, 0..1 for integer formats, alpha as stored.
  Outcome (*read)(const std::string& path, const std::string& reader, const unsigned char* bytes,
                  std::size_t size, Image& out, std::string& reason);
};

}  // namespace nmbake::oiio_module

extern "C" const nmbake::oiio_module::Api* nmbake_oiio_module_api();
