// Stage "dilate": grow chart borders outward so mipmaps and bilinear
// filtering never see the background.
//
// Each pass fills every empty texel that has covered 8-neighbours with the
// normalised mean of their decoded vectors (rgb -> 2 rgb - 1), then marks it
// covered; `padding` passes. Passes read one buffer and write another, so the
// result does not depend on the order of the texels or on the thread count.
#pragma once

#include <cstdint>
#include <vector>

#include "nmbake/image.hpp"

namespace nmbake {

struct DilateStats {
  std::uint64_t filled_texels = 0;
};

// `coverage` has one entry per texel (1 = covered) and is updated.
void dilate(Image& image, std::vector<std::uint8_t>& coverage, int padding, DilateStats& stats);

}  // namespace nmbake
