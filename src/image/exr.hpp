// Private to the write stage: nmbake's own OpenEXR writer (see image_exr.cpp).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "nmbake/common.hpp"
#include "nmbake/image.hpp"

namespace nmbake::image_detail {

// Scanlines per chunk of ZIP compression (fixed by the format).
constexpr int kExrZipLines = 16;

// The whole EXR file of `image` (1 to 4 channels: Y, YA, RGB, RGBA), 32-bit
// float or 16-bit half samples, ZIP compression, one part of scanlines.
std::vector<std::uint8_t> encode_exr(const Image& image, bool half);

// encode_exr() written to `path`; io error naming `display_path` on failure.
Status write_exr(const Image& image, bool half, const std::string& path, const std::string& display_path);

// IEEE 754 binary16 of a float, rounded to nearest even (overflow to
// infinity, NaN kept NaN): what OpenEXR's half type stores. Exposed for tests.
std::uint16_t float_to_half(float value);

}  // namespace nmbake::image_detail
