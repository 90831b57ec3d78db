// Angular difference of two normal maps (the regression gate). The decode is
// the one of the encode stage (rgb = 0.5 n + 0.5, DESIGN.md); the angle is
// atan2(|a x b|, a . b), which stays accurate near 0 where acos(a . b) loses
// all precision (acos(1 - 1e-8) is already 0.008 degrees).
#include "nmbake/diff.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/ext/vector_double3.hpp>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>
#include <numbers>
#include <vector>

namespace nmbake {

const char* to_string(Quantisation q) {
  switch (q) {
    case Quantisation::none:
      return "float";
    case Quantisation::half:
      return "half";
    case Quantisation::uint16:
      return "uint16";
    case Quantisation::uint8:
      return "uint8";
  }
  return "float";
}

Quantisation quantisation_of_data_type(const std::string& data_type) {
  if (data_type == "uint8" || data_type == "int8") return Quantisation::uint8;
  if (data_type == "uint16" || data_type == "int16") return Quantisation::uint16;
  if (data_type == "half") return Quantisation::half;
  return Quantisation::none;
}

namespace {
int precision_rank(Quantisation q) {
  switch (q) {
    case Quantisation::uint8:
      return 0;
    case Quantisation::half:
      return 1;
    case Quantisation::uint16:
      return 2;
    case Quantisation::none:
      return 3;
  }
  return 3;
}
}  // namespace

Quantisation coarser(Quantisation a, Quantisation b) {
  return precision_rank(a) <= precision_rank(b) ? a : b;
}

float quantise(float value, Quantisation q) {
  const float v = std::clamp(value, 0.0f, 1.0f);
  switch (q) {
    case Quantisation::none:
      return value;
    case Quantisation::uint8:
      return std::round(v * 255.0f) / 255.0f;
    case Quantisation::uint16:
      return std::round(v * 65535.0f) / 65535.0f;
    case Quantisation::half: {
      // Normal halves keep 11 significant bits; below 2^-14 the step is a
      // fixed 2^-24 (subnormals).
      if (v < 0x1p-14f) return std::round(v * 0x1p24f) * 0x1p-24f;
      int exponent = 0;
      const float mantissa = std::frexp(v, &exponent);  // [0.5, 1)
      return std::ldexp(std::round(mantissa * 2048.0f) / 2048.0f, exponent);
    }
  }
  return value;
}

double DiffStats::share_over_one_degree() const {
  return compared_texels > 0 ? static_cast<double>(over_one_degree) / static_cast<double>(compared_texels)
                             : 0.0;
}

double DiffStats::share_changed() const {
  return compared_texels > 0 ? static_cast<double>(changed_texels) / static_cast<double>(compared_texels)
                             : 0.0;
}

std::string DiffStats::summary_line() const {
  char line[512];
  std::snprintf(line, sizeof line,
                "diff %dx%d: %llu texels, mean %.3f deg, median %.3f, p95 %.3f, p99 %.3f, max %.3f; "
                "over 1 deg %.3f%%; changed %llu (%.3f%%, at %s)",
                width, height, static_cast<unsigned long long>(compared_texels), mean, median, p95, p99, max,
                100.0 * share_over_one_degree(), static_cast<unsigned long long>(changed_texels),
                100.0 * share_changed(), to_string(quantisation));
  std::string out = line;
  if (degenerate_texels > 0) {
    out += "; " + std::to_string(degenerate_texels) + " texels without a direction";
  }
  return out;
}

std::string DiffStats::to_json() const {
  nlohmann::ordered_json j;
  j["width"] = width;
  j["height"] = height;
  j["compared_texels"] = compared_texels;
  j["mean_deg"] = mean;
  j["median_deg"] = median;
  j["p95_deg"] = p95;
  j["p99_deg"] = p99;
  j["max_deg"] = max;
  j["over_one_degree"] = over_one_degree;
  j["share_over_one_degree"] = share_over_one_degree();
  j["changed_texels"] = changed_texels;
  j["share_changed"] = share_changed();
  j["changed_at"] = to_string(quantisation);
  j["degenerate_texels"] = degenerate_texels;
  return j.dump(2);
}

namespace {

constexpr double kDegenerateLength = 1e-6;

glm::dvec3 decode(const float* rgb) { return {2.0 * rgb[0] - 1.0, 2.0 * rgb[1] - 1.0, 2.0 * rgb[2] - 1.0}; }

// Heat-map ramp: black -> blue -> yellow -> red.
void ramp(double x, float* rgb) {
  static constexpr float kStops[4][3] = {{0, 0, 0}, {0, 0, 1}, {1, 1, 0}, {1, 0, 0}};
  const double t = std::clamp(x, 0.0, 1.0) * 3.0;
  const int i = std::min(static_cast<int>(t), 2);
  const float f = static_cast<float>(t - i);
  for (int c = 0; c < 3; ++c) rgb[c] = kStops[i][c] + (kStops[i + 1][c] - kStops[i][c]) * f;
}

// Nearest rank: the smallest value with at least `p` of the values at or below it.
double percentile(std::vector<float>& values, double p) {
  const std::size_t n = values.size();
  std::size_t rank = static_cast<std::size_t>(std::ceil(p * static_cast<double>(n)));
  rank = std::clamp<std::size_t>(rank, 1, n);
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(rank - 1), values.end());
  return values[rank - 1];
}

}  // namespace

Status diff_images(const Image& a, const Image& b, const Image* mask, const DiffOptions& options,
                   DiffStats& stats, Image* heatmap) {
  stats = DiffStats{};
  if (a.width <= 0 || a.height <= 0 || a.pixels.empty()) return Status::bad_input("first map is empty");
  if (a.channels < 3 || b.channels < 3) return Status::bad_input("a normal map needs at least 3 channels");
  if (a.width != b.width || a.height != b.height) {
    return Status::bad_input("map sizes differ: " + std::to_string(a.width) + "x" + std::to_string(a.height) +
                             " and " + std::to_string(b.width) + "x" + std::to_string(b.height));
  }
  if (mask && (mask->width != a.width || mask->height != a.height || mask->channels < 1)) {
    return Status::bad_input("mask size " + std::to_string(mask->width) + "x" + std::to_string(mask->height) +
                             " differs from the maps' " + std::to_string(a.width) + "x" +
                             std::to_string(a.height));
  }
  stats.width = a.width;
  stats.height = a.height;
  stats.quantisation = options.quantisation;
  const std::size_t texel_count = static_cast<std::size_t>(a.width) * static_cast<std::size_t>(a.height);
  const double flip = options.green_b == GreenChannel::down ? -1.0 : 1.0;

  // Per texel: angle in degrees (negative = outside the mask) and flags;
  // every texel depends on its own index only, so rows run in parallel and
  // the serial reductions below see the same values whatever the threads.
  std::vector<float> angle(texel_count);
  std::vector<std::uint8_t> flags(texel_count);  // 1 changed, 2 degenerate
  tbb::parallel_for(tbb::blocked_range<int>(0, a.height), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < a.width; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(a.width) + x;
        if (mask && !(mask->at(x, y)[0] > 0.5f)) {
          angle[i] = -1.0f;
          flags[i] = 0;
          continue;
        }
        const float* pa = a.at(x, y);
        const float* pb = b.at(x, y);
        glm::dvec3 na = decode(pa);
        glm::dvec3 nb = decode(pb);
        nb.y *= flip;
        std::uint8_t f = 0;
        for (int c = 0; c < 3; ++c) {
          float vb = pb[c];
          if (c == 1 && flip < 0.0) vb = 1.0f - vb;
          if (quantise(pa[c], options.quantisation) != quantise(vb, options.quantisation)) f |= 1;
        }
        const double la = glm::length(na), lb = glm::length(nb);
        double degrees = 0.0;
        if (la < kDegenerateLength || lb < kDegenerateLength) {
          f |= 2;
          degrees = (la < kDegenerateLength) == (lb < kDegenerateLength) ? 0.0 : 90.0;
        } else {
          degrees =
              std::atan2(glm::length(glm::cross(na, nb)), glm::dot(na, nb)) * (180.0 / std::numbers::pi);
        }
        angle[i] = static_cast<float>(degrees);
        flags[i] = f;
      }
    }
  });

  std::vector<float> compared;
  compared.reserve(texel_count);
  double sum = 0.0;
  for (std::size_t i = 0; i < texel_count; ++i) {
    if (angle[i] < 0.0f) continue;
    compared.push_back(angle[i]);
    sum += angle[i];
    stats.max = std::max(stats.max, static_cast<double>(angle[i]));
    if (angle[i] > 1.0f) ++stats.over_one_degree;
    if (flags[i] & 1) ++stats.changed_texels;
    if (flags[i] & 2) ++stats.degenerate_texels;
  }
  stats.compared_texels = compared.size();

  if (heatmap) {
    heatmap->width = a.width;
    heatmap->height = a.height;
    heatmap->channels = 3;
    heatmap->pixels.assign(texel_count * 3, 0.2f);
    const double top = options.heatmap_max_degrees > 0.0f ? options.heatmap_max_degrees : 1.0;
    for (std::size_t i = 0; i < texel_count; ++i) {
      if (angle[i] >= 0.0f) ramp(angle[i] / top, heatmap->pixels.data() + i * 3);
    }
  }

  if (!compared.empty()) {
    stats.mean = sum / static_cast<double>(compared.size());
    stats.median = percentile(compared, 0.5);
    stats.p95 = percentile(compared, 0.95);
    stats.p99 = percentile(compared, 0.99);
  }
  return Status::ok();
}

Status diff_files(const std::string& path_a, const std::string& path_b, const std::string& mask_path,
                  DiffOptions options, DiffStats& stats, Image* heatmap) {
  ImageFileInfo info_a, info_b;
  NMBAKE_TRY(read_image_info(path_a, info_a));
  NMBAKE_TRY(read_image_info(path_b, info_b));
  if (info_a.width != info_b.width || info_a.height != info_b.height) {
    return Status::bad_input("map sizes differ: " + path_a + " is " + std::to_string(info_a.width) + "x" +
                             std::to_string(info_a.height) + ", " + path_b + " is " +
                             std::to_string(info_b.width) + "x" + std::to_string(info_b.height));
  }
  if (info_a.channels < 3)
    return Status::bad_input(path_a + ": a normal map needs 3 channels, it has " +
                             std::to_string(info_a.channels));
  if (info_b.channels < 3)
    return Status::bad_input(path_b + ": a normal map needs 3 channels, it has " +
                             std::to_string(info_b.channels));
  options.quantisation =
      coarser(quantisation_of_data_type(info_a.data_type), quantisation_of_data_type(info_b.data_type));

  Image a, b, mask;
  NMBAKE_TRY(read_image(path_a, a));
  NMBAKE_TRY(read_image(path_b, b));
  if (!mask_path.empty()) {
    NMBAKE_TRY(read_image(mask_path, mask));
    if (mask.width != a.width || mask.height != a.height) {
      return Status::bad_input(mask_path + ": mask is " + std::to_string(mask.width) + "x" +
                               std::to_string(mask.height) + ", the maps are " + std::to_string(a.width) +
                               "x" + std::to_string(a.height));
    }
  }
  return diff_images(a, b, mask_path.empty() ? nullptr : &mask, options, stats, heatmap);
}

}  // namespace nmbake
