// Private to src/bake/: the images of --debug-dump (BakeOptions::debug_dump_prefix).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "nmbake/common.hpp"
#include "nmbake/image.hpp"
#include "nmbake/raster.hpp"
#include "nmbake/trace.hpp"

namespace nmbake::detail {

// Per texel: covered, share of missed samples, mean signed hit distance;
// filled band by band.
struct DebugImages {
  Image coverage, misses, distance, refined;
  bool adaptive = false;
  DebugImages(int width, int height, bool adaptive_bake);
  void add_band(const TexelSamples& samples, const Hits& hits);
  // Adaptive sampling: the texels a level chose (band indices of the band
  // starting at image row `row_begin`), drawn with `value` (the last level
  // white).
  void add_refined(int row_begin, const std::vector<std::uint32_t>& texels, float value);
  // <prefix>_coverage.png, _misses.png, _distance.exr (and _refined.png when adaptive).
  Status write(const std::string& prefix) const;
};

}  // namespace nmbake::detail
