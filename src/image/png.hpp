// Private to the write stage: nmbake's own PNG encoder (see image_png.cpp).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "nmbake/common.hpp"
#include "nmbake/image.hpp"

namespace nmbake::image_detail {

// Rows deflated as one independent piece. Fixed (never derived from the
// thread count) so the file's bytes are the same on any machine.
constexpr std::size_t kPngGroupBytes = std::size_t{1} << 18;

// The whole PNG file (signature to IEND) of `image` at 8 or 16 bits per
// channel, values quantised as round(clamp(v, 0, 1) * max). 1 to 4 channels:
// grey, grey + alpha, RGB, RGBA. `dither` (8 bits only): ordered dithering
// instead of rounding (quantise.hpp). Each value is first mapped to
// v * scale + offset (WriteOptions), in the quantiser: no mapped copy.
std::vector<std::uint8_t> encode_png(const Image& image, int bits, bool dither = false, float scale = 1.0f,
                                     float offset = 0.0f);

// encode_png() written to `path`; io error naming `display_path` on failure.
Status write_png(const Image& image, int bits, const std::string& path, const std::string& display_path,
                 bool dither = false, float scale = 1.0f, float offset = 0.0f);

}  // namespace nmbake::image_detail
