// The images of --debug-dump (debug_images.hpp).
#include "bake/debug_images.hpp"

#include <cstddef>

namespace nmbake::detail {

DebugImages::DebugImages(int width, int height, bool adaptive_bake) : adaptive(adaptive_bake) {
  for (Image* image : {&coverage, &misses, &distance, &refined}) {
    image->width = width;
    image->height = height;
    image->channels = 3;
    image->pixels.assign(static_cast<std::size_t>(width) * height * 3, 0.0f);
  }
}

void DebugImages::add_band(const TexelSamples& samples, const Hits& hits) {
  const std::size_t texels = static_cast<std::size_t>(samples.width) * samples.height;
  const std::size_t offset = static_cast<std::size_t>(samples.row_begin) * samples.width;
  for (std::size_t t = 0; t < texels; ++t) {
    int traced = 0, missed = 0;
    double sum = 0.0;
    for (int k = 0; k < samples.samples; ++k) {
      const std::size_t s = t * samples.samples + k;
      if (samples.triangle[s] < 0) continue;
      ++traced;
      if (hits.triangle[s] < 0) {
        ++missed;
      } else {
        sum += hits.distance[s];
      }
    }
    const float c = samples.coverage[t] ? 1.0f : 0.0f;
    const float m = traced > 0 ? static_cast<float>(missed) / traced : 0.0f;
    const float d = traced > missed ? static_cast<float>(sum / (traced - missed)) : 0.0f;
    for (int ch = 0; ch < 3; ++ch) {
      coverage.pixels[(offset + t) * 3 + ch] = c;
      misses.pixels[(offset + t) * 3 + ch] = ch == 0 ? m : 0.0f;
      distance.pixels[(offset + t) * 3 + ch] = d;
    }
  }
}

void DebugImages::add_refined(int row_begin, const std::vector<std::uint32_t>& texels, float value) {
  const std::size_t offset = static_cast<std::size_t>(row_begin) * refined.width;
  for (const std::uint32_t t : texels) {
    for (int ch = 0; ch < 3; ++ch) refined.pixels[(offset + t) * 3 + ch] = value;
  }
}

Status DebugImages::write(const std::string& prefix) const {
  if (adaptive) NMBAKE_TRY(write_image(refined, prefix + "_refined.png", PixelFormat::png8));
  NMBAKE_TRY(write_image(coverage, prefix + "_coverage.png", PixelFormat::png8));
  NMBAKE_TRY(write_image(misses, prefix + "_misses.png", PixelFormat::png8));
  NMBAKE_TRY(write_image(distance, prefix + "_distance.exr", PixelFormat::exr_float));
  return Status::ok();
}

}  // namespace nmbake::detail
