// Adaptive sampling of a bake's rows (adaptive_rows.hpp).
#include "bake/adaptive_rows.hpp"

#include <algorithm>
#include <cstddef>
#include <iterator>

#include "bake/report_fill.hpp"

namespace nmbake::detail {

AdaptiveRows::AdaptiveRows(const Prepared& p, const LowSurface& surface, BakeReport& r, Image& image,
                           std::vector<std::uint8_t>& coverage, const EncodeOptions& encode_options,
                           DebugImages* debug)
    : p_(p),
      o_(p.options),
      surface_(surface),
      r_(r),
      image_(image),
      coverage_(coverage),
      encode_(encode_options),
      debug_(debug),
      texel_size_(texel_sizes(surface, p.options.width, p.options.height)),
      levels_(adaptive_levels(p.options.adaptive_options)) {}

void AdaptiveRows::run(int first_row, int last_row, StageTimer& timer, const ProgressFn& progress,
                       std::uint64_t& covered_texels) {
  timer_ = &timer;
  const int rows_per_band = band_rows(o_.width, o_.height, 1, o_.band_samples);
  r_.adaptive.max_samples = o_.adaptive_options.max_samples;
  r_.adaptive.level_texels.assign(levels_.size(), 0);
  r_.adaptive.level_rays.assign(levels_.size(), 0);
  FirstPass above, below;
  if (first_row > 0) {
    first_pass(halo_, std::max(0, first_row - kRasterTileSize), first_row, false);
    above = first_pass_row(halo_.values, halo_.values.rows - 1);
  }
  first_pass(bands_[0], first_row, std::min(first_row + rows_per_band, last_row), true);
  int k = 0;
  for (int row = first_row; row < last_row; row += rows_per_band, ++k) {
    Band& band = bands_[k % 2];
    const int row_end = std::min(row + rows_per_band, last_row);
    if (row_end < last_row) {
      Band& next = bands_[(k + 1) % 2];
      first_pass(next, row_end, std::min(row_end + rows_per_band, last_row), true);
      below = first_pass_row(next.values, 0);
    } else if (last_row < o_.height) {
      first_pass(halo_, last_row, std::min(last_row + kRasterTileSize, o_.height), false);
      below = first_pass_row(halo_.values, 0);
    } else {
      below = FirstPass{};
    }
    timer.start_quietly("adaptive");
    refine_texels(above, band.values, below, o_.adaptive_options, chosen_);
    timer.stop(false);
    // The first pass's values, then the refined texels' over them.
    std::copy(band.values.rgb.begin(), band.values.rgb.end(),
              image_.pixels.begin() + static_cast<std::ptrdiff_t>(row - first_row) * o_.width * 3);
    covered_texels += band.covered;
    std::copy(band.samples.coverage.begin(), band.samples.coverage.end(),
              coverage_.begin() + static_cast<std::ptrdiff_t>(row - first_row) * o_.width);
    if (debug_ != nullptr) debug_->add_band(band.samples, band.hits);
    refine_level(0, chosen_, row, row_end, first_row);
    above = first_pass_row(band.values, band.values.rows - 1);
    if (progress) progress("trace", static_cast<double>(row_end - first_row) / (last_row - first_row));
  }
  r_.adaptive.refined_texels = r_.adaptive.level_texels[0];
}

void AdaptiveRows::first_pass(Band& band, int row_begin, int row_end, bool counted) {
  timer_->start_quietly("raster");
  RasterStats raster;
  rasterize(surface_, o_.width, o_.height, 1, band.samples, raster, row_begin, row_end);
  timer_->stop(false);
  timer_->start_quietly("trace");
  TraceStats traced;
  trace(p_.scene, surface_, band.samples, p_.rays, band.hits, traced);
  timer_->stop(false);
  timer_->start_quietly("encode");
  EncodeOptions band_encode = encode_;
  band_encode.out_row_begin = row_begin;
  band.image.height = 0;
  EncodeStats encoded;
  encode(surface_, band.samples, p_.high, band.hits, band_encode, band.image, counted ? r_.encode : encoded);
  band.values.rgb.swap(band.image.pixels);
  timer_->stop(false);
  timer_->start_quietly("adaptive");
  first_pass_values(band.samples, band.hits, texel_size_, band.values);
  timer_->stop(false);
  band.covered = raster.covered_texels;
  if (!counted) {
    r_.adaptive.halo_rays += traced.rays;
    return;
  }
  report_raster_band(raster, r_);
  add(r_.trace, traced);
  r_.adaptive.first_pass_rays += traced.rays;
}

void AdaptiveRows::refine_level(std::size_t level, const std::vector<std::uint32_t>& texels, int row_begin,
                                int row_end, int first_row) {
  if (level >= std::size(level_)) return;  // levels_ holds at most two refinement levels
  const int n = levels_[level];
  const bool last = level + 1 == levels_.size();
  Level& l = level_[level];
  const std::size_t band_samples = o_.band_samples > 0 ? o_.band_samples : std::size_t{1} << 20;
  const std::size_t chunk = std::max<std::size_t>(1, band_samples / static_cast<std::size_t>(n));
  r_.adaptive.level_texels[level] += texels.size();
  if (debug_ != nullptr)
    debug_->add_refined(row_begin, texels, static_cast<float>(level + 1) / levels_.size());
  EncodeOptions compact_encode = encode_;
  compact_encode.out_row_begin = 0;
  for (std::size_t begin = 0; begin < texels.size(); begin += chunk) {
    const std::size_t count = std::min(chunk, texels.size() - begin);
    timer_->start_quietly("raster");
    RasterStats raster;
    rasterize_selected(surface_, o_.width, o_.height, n, row_begin, row_end, texels.data() + begin, count,
                       l.samples, raster, slot_);
    r_.raster.border_samples += raster.border_samples;
    r_.raster.overlapping_samples += raster.overlapping_samples;
    timer_->stop(false);
    timer_->start_quietly("trace");
    TraceStats traced;
    trace(p_.scene, surface_, l.samples, p_.rays, l.hits, traced);
    add(r_.trace, traced);
    r_.adaptive.level_rays[level] += traced.rays;
    timer_->stop(false);
    timer_->start_quietly("encode");
    l.image.height = 0;
    encode(surface_, l.samples, p_.high, l.hits, compact_encode, l.image, r_.encode);
    // Into the image rows of the band (the image holds rows from first_row).
    const std::size_t offset =
        static_cast<std::size_t>(row_begin - first_row) * static_cast<std::size_t>(o_.width);
    for (std::size_t i = 0; i < count; ++i) {
      std::copy_n(&l.image.pixels[i * 3], 3, &image_.pixels[(offset + texels[begin + i]) * 3]);
    }
    timer_->stop(false);
    if (last) continue;
    timer_->start_quietly("adaptive");
    l.next.clear();
    spread_texels(l.samples, l.hits, p_.high, encode_.high_normals == HighNormals::smooth,
                  texels.data() + begin, o_.adaptive_options, l.next);
    timer_->stop(false);
    refine_level(level + 1, l.next, row_begin, row_end, first_row);
  }
}

void AdaptiveRows::add(TraceStats& to, const TraceStats& from) {
  to.rays += from.rays;
  to.samples += from.samples;
  to.hits += from.hits;
  to.misses += from.misses;
  to.ray_fallbacks += from.ray_fallbacks;
}

}  // namespace nmbake::detail
