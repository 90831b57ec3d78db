// Comparing two normal maps: the regression-bake gate behind `nmbake diff`.
//
// Both maps are decoded as a renderer would for a flat frame: n = 2 rgb - 1,
// normalised (tangent- and object-space maps alike), and compared texel by
// texel by the angle between the two vectors, in degrees (atan2(|a x b|,
// a . b) in double precision, exact also for tiny angles). For a tangent-space
// map that is the angle a renderer shows wherever the frame is orthonormal;
// on a skewed interpolated frame the shaded angle differs slightly, but two
// maps of one low mesh share that frame, so the ranking of changes holds.
//
// Only the first three channels are read (alpha is ignored). Maps of any
// bit depth and format compare; the sizes must be equal.
#pragma once

#include <cstdint>
#include <string>

#include "nmbake/common.hpp"
#include "nmbake/encode.hpp"
#include "nmbake/image.hpp"

namespace nmbake {

// How finely a file's values are stored: a "changed" texel is one whose
// values differ after both maps are rounded to the coarser of the two.
enum class Quantisation : std::uint8_t {
  none,    // 32-bit float (or anything finer than 16 bits): compared as stored
  half,    // 16-bit float: 11 significant bits
  uint16,  // 1/65535 steps
  uint8,   // 1/255 steps
};
const char* to_string(Quantisation q);
// From ImageFileInfo::data_type ("uint8", "uint16", "half", "float", ...);
// unknown types are taken as `none`.
Quantisation quantisation_of_data_type(const std::string& data_type);
// The coarser of two (uint8 < half < uint16 < none in precision).
Quantisation coarser(Quantisation a, Quantisation b);
// Rounds a value in [0, 1] as a file of that type stores it.
float quantise(float value, Quantisation q);

struct DiffOptions {
  // `down`: negate y of the second map before comparing (an OpenGL bake `a`
  // against a DirectX bake `b`).
  GreenChannel green_b = GreenChannel::up;
  Quantisation quantisation = Quantisation::none;  // for changed_texels; the coarser of the two maps
  float heatmap_max_degrees = 5.0f;                // the top of the heat-map ramp
};

struct DiffStats {
  int width = 0, height = 0;
  std::uint64_t compared_texels = 0;  // texels inside the mask (all texels without one)
  std::uint64_t changed_texels = 0;   // values differ after rounding to options.quantisation
  std::uint64_t over_one_degree = 0;  // angle > 1 degree
  // Texels where a decoded vector has length < 1e-6 (rgb ~ 0.5 grey, e.g. the
  // background of an object-space map): the angle is 0 when both are, 90
  // degrees when only one is (a normal lost or gained is a full change).
  std::uint64_t degenerate_texels = 0;
  // Angles in degrees over the compared texels; percentiles are nearest-rank
  // (the smallest angle with at least p of the texels at or below it). All
  // 0 when no texel is compared.
  double mean = 0.0, median = 0.0, p95 = 0.0, p99 = 0.0, max = 0.0;
  Quantisation quantisation = Quantisation::none;

  double share_over_one_degree() const;  // over_one_degree / compared_texels
  double share_changed() const;
  std::string summary_line() const;  // one line, no newline
  std::string to_json() const;       // keys: width, height, compared_texels, mean_deg, ...
};

// Compares two decoded images. `mask`, when not null, selects texels whose
// first channel is > 0.5. `heatmap`, when not null, receives a width x height
// RGB image of the angle: black (0) -> blue -> yellow -> red (>=
// heatmap_max_degrees), linear between the stops at 0, 1/3, 2/3 and 1 of the
// range; texels outside the mask are dark grey (0.2).
// Errors (bad_input): an image with fewer than 3 channels, sizes that differ
// (also the mask's), empty images.
Status diff_images(const Image& a, const Image& b, const Image* mask, const DiffOptions& options,
                   DiffStats& stats, Image* heatmap);

// Reads the files (and the quantisation of each from its header), then
// diff_images with options.quantisation set to the coarser of the two.
// Paths appear in every message. mask_path may be empty.
Status diff_files(const std::string& path_a, const std::string& path_b, const std::string& mask_path,
                  DiffOptions options, DiffStats& stats, Image* heatmap);

}  // namespace nmbake
