// A float RGB(A) image in memory, and the "write" stage: OpenImageIO writers
// for 8/16-bit PNG, 16-bit TIFF, half/float EXR, written to a temporary file
// in the target's folder and renamed, so a failed bake never leaves a
// half-written map. OpenImageIO types stay in image.cpp.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "nmbake/common.hpp"

namespace nmbake {

struct Image {
  int width = 0;
  int height = 0;
  int channels = 3;
  std::vector<float> pixels;  // row-major, y = 0 the top row, interleaved channels

  float* at(int x, int y) { return pixels.data() + (static_cast<std::size_t>(y) * width + x) * channels; }
  const float* at(int x, int y) const {
    return pixels.data() + (static_cast<std::size_t>(y) * width + x) * channels;
  }
};

enum class PixelFormat : std::uint8_t { png8, png16, tiff16, exr_half, exr_float };

const char* to_string(PixelFormat format);
// "png8", "png16", "tiff16", "exr-half", "exr-float".
bool parse_pixel_format(const std::string& text, PixelFormat& out);
// From the file extension: .png -> png16, .tif/.tiff -> tiff16, .exr -> exr_float.
bool pixel_format_from_path(const std::string& path, PixelFormat& out);
// Whether `format` can be written to a file with this extension.
bool format_matches_extension(PixelFormat format, const std::string& path);

// Values are written as they are (no colour transform, no sRGB): integer
// formats quantise round(clamp(v, 0, 1) * max).
Status write_image(const Image& image, const std::string& path, PixelFormat format);

// Reads any format OpenImageIO reads into float, 0..1 for integer formats.
Status read_image(const std::string& path, Image& out);

}  // namespace nmbake
