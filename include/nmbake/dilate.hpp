// Stage "dilate": grow chart borders outward so mipmaps and bilinear
// filtering never see the background.
//
// Each pass fills every empty texel that has covered 8-neighbours with the
// normalised mean of their decoded vectors (rgb -> 2 rgb - 1), then marks it
// covered; `padding` passes. Passes read one buffer and write another, so the
// result does not depend on the order of the texels or on the thread count.
//
// Details (dilate.cpp): the image must have at least 3 channels; channels
// after the third (alpha) get the plain mean of the same neighbours. The
// image does not wrap: texels outside it are not neighbours. When the
// neighbours' vectors cancel (squared length of their sum < 1e-12) the texel
// copies, all channels, the first covered neighbour in row-major order
// (up-left, up, up-right, left, right, down-left, down, down-right) and
// counts in `fallback_texels`. Only texels on the growing frontier are
// visited, so the cost is one scan of the coverage plus the filled texels.
#pragma once

#include <cstdint>
#include <vector>

#include "nmbake/image.hpp"

namespace nmbake {

// How a filled texel is computed from its covered neighbours (before this
// pass):
//   * unit_vector (normal maps): the normalised mean of the decoded vectors of
//     the first three channels, as above; the image needs 3 or more channels;
//   * mean (scalar and colour maps: height, AO, position...): the plain mean
//     of every channel, in the fixed neighbour order;
//   * nearest (labels: the miss mask, ids): a copy of the first covered
//     neighbour in the fixed order (never a blend of two labels).
enum class DilateMode : std::uint8_t { unit_vector, mean, nearest };

struct DilateStats {
  std::uint64_t filled_texels = 0;
  // Texels whose neighbours' vectors cancelled (see above). Added to the
  // lead's contract by the dilate stage.
  std::uint64_t fallback_texels = 0;
};

// `coverage` has one entry per texel (1 = covered) and is updated.
// Every entry must be 0 or 1. `stats` is overwritten with this call's counts.
void dilate(Image& image, std::vector<std::uint8_t>& coverage, int padding, DilateStats& stats,
            DilateMode mode = DilateMode::unit_vector);

// Several images of one size over one coverage (a map set), each with its
// mode: the rings are found once, and each image gets exactly the values
// dilate() would give it alone. fallback_texels counts every image's.
struct DilateLayer {
  Image* image = nullptr;
  DilateMode mode = DilateMode::unit_vector;
};
void dilate(const std::vector<DilateLayer>& layers, std::vector<std::uint8_t>& coverage, int padding,
            DilateStats& stats);

}  // namespace nmbake
