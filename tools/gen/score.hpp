// Scoring a baked map against an analytic scene's true normals, texel by
// texel, in degrees. The truth is computed along the bake's own rays (same
// raster, same cage), so what is measured is the baker's error: the high
// mesh's discretisation, the tangent frame, the encode and the quantisation.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "nmbake/image.hpp"
#include "nmbake/mesh.hpp"
#include "scenes.hpp"

namespace nmbake::scenes {

struct AngularError {
  std::size_t texels = 0;      // texels scored
  std::size_t non_finite = 0;  // NaN/Inf values anywhere in the map
  double mean = 0.0, median = 0.0, p95 = 0.0, p99 = 0.0, max = 0.0;
  double over_1deg = 0.0, over_5deg = 0.0;  // shares of the scored texels
  std::string to_text() const;
};

AngularError summarize_errors(std::vector<float> errors_degrees, std::size_t non_finite);

// Heightfield: the low grid is flat with u = x / size, v = y / size, so the
// frame is the identity; the expected texel is the normalised mean of the
// analytic normals at the sample positions.
AngularError score_heightfield(const HeightfieldParams& params, const Image& map, int samples);

// Displaced sphere, tangent-space map baked with the averaged cage and the
// given (resolved) front/back distances: each sample's ray is intersected
// with the analytic surface, its analytic normal encoded with the exact
// inverse through the sample's frame and averaged like the baker does; baked
// and expected texels are decoded through the frame of the texel's first
// sample and compared. `low` is the low mesh as baked (unit normals, UVs).
AngularError score_sphere(const SphereParams& params, const Mesh& low, const Image& map, int samples,
                          float front, float back);

}  // namespace nmbake::scenes
