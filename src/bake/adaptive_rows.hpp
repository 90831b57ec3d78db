// Private to src/bake/: adaptive sampling (adaptive.hpp) of a bake's rows.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "bake/debug_images.hpp"
#include "bake/pipeline.hpp"
#include "nmbake/adaptive.hpp"
#include "nmbake/bake.hpp"
#include "nmbake/encode.hpp"
#include "nmbake/image.hpp"
#include "nmbake/raster.hpp"
#include "nmbake/surface.hpp"
#include "nmbake/trace.hpp"

namespace nmbake::detail {

// Adaptive sampling (adaptive.hpp), rows [first_row, last_row) of the map
// into `image` and `coverage` (which hold only those rows), band by band:
// each band's first pass (one sample a texel: rasterize, trace, encode),
// then the texels level 1 chose again with the 4-sample pattern, in chunks,
// compactly (rasterize_selected), and of those the ones level 2 chose with
// max_samples; each level's values written over the one before. Level 1
// reads the row above and below each band, so the next band's first pass
// runs before a band is refined, and a tile of rows first traces the rows
// just outside it (not counted as its rays).
class AdaptiveRows {
 public:
  AdaptiveRows(const Prepared& p, const LowSurface& surface, BakeReport& r, Image& image,
               std::vector<std::uint8_t>& coverage, const EncodeOptions& encode_options, DebugImages* debug);

  void run(int first_row, int last_row, StageTimer& timer, const ProgressFn& progress,
           std::uint64_t& covered_texels);

 private:
  struct Band {
    TexelSamples samples;
    Hits hits;
    FirstPass values;  // with the encoded first pass (kept: the rule needs it after the next band's)
    Image image;       // scratch of the encode
    std::uint64_t covered = 0;
  };
  // The compact buffers of one level.
  struct Level {
    TexelSamples samples;
    Hits hits;
    Image image;
    std::vector<std::uint32_t> next;  // the texels of the level after this one
  };

  // One sample a texel for rows [row_begin, row_end), encoded; `counted`:
  // rows of this bake (not the halo of a tile).
  void first_pass(Band& band, int row_begin, int row_end, bool counted);

  // `texels` (band indices, ascending) with level `level`'s pattern, in
  // chunks of about a band's samples, each value written over the one
  // before; the texels the next level takes go on to it chunk by chunk.
  void refine_level(std::size_t level, const std::vector<std::uint32_t>& texels, int row_begin, int row_end,
                    int first_row);

  static void add(TraceStats& to, const TraceStats& from);

  const Prepared& p_;
  const BakeOptions& o_;
  const LowSurface& surface_;
  BakeReport& r_;
  Image& image_;
  std::vector<std::uint8_t>& coverage_;
  const EncodeOptions& encode_;
  DebugImages* debug_;
  StageTimer* timer_ = nullptr;
  std::vector<float> texel_size_;
  std::vector<int> levels_;
  Band bands_[2], halo_;
  Level level_[2];
  std::vector<std::uint32_t> chosen_, slot_;
};

}  // namespace nmbake::detail
