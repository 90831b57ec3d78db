// The lab's evaluator: scores a baked map of any analytic scene against the
// scene's true normals, texel by texel, in degrees.
//
// The truth is taken along the bake's own rays (make_ray with the bake's cage
// and distances): for every sample, the analytic surface is intersected along
// the ray and the crossing kept is the front-facing one (entering the surface
// from outside) nearest to the low surface point — the high surface the low
// point stands for. That rule is fixed, whatever the bake's own hit rule, so
// a bake that keeps a wrong surface (the far wall of a groove, a back face)
// or misses shows its error in degrees. Samples whose ray meets no analytic
// surface are not scored (counted as "without truth").
//
// The expected texel is the box-filtered truth: the average over a fixed,
// dense set of samples of the texel (truth_samples, 64 by default) whatever
// the bake's sample count, so a 1-sample bake pays for its aliasing.
//
// A map is always decoded as a renderer does: tangent space through the low
// mesh's MikkTSpace frame (tangent_to_world), whatever basis it was baked in;
// object space directly. The expected texel is the analytic normal encoded
// with the exact inverse through each sample's frame, averaged over the
// texel's samples like the baker averages, so a perfect bake scores 0 up to
// float rounding when truth_samples equals the bake's; expected_image() gives that perfect map, for
// validating the evaluator and measuring the quantisation floors.
#pragma once

#include <cstddef>
#include <glm/ext/vector_double3.hpp>
#include <memory>
#include <string>
#include <vector>

#include "lab_scenes.hpp"
#include "nmbake/encode.hpp"
#include "nmbake/image.hpp"
#include "nmbake/mesh.hpp"
#include "nmbake/trace.hpp"
#include "score.hpp"

namespace nmbake::scenes {

// A true surface as one or more patches, each a signed field (> 0 outside)
// with an analytic normal, and the marching step that cannot skip a crossing.
class TrueSurface {
 public:
  virtual ~TrueSurface() = default;
  virtual int patch_count() const { return 1; }
  virtual double field(int patch, const glm::dvec3& x) const = 0;
  virtual glm::dvec3 normal(int patch, const glm::dvec3& x) const = 0;  // unit, at a surface point
  virtual bool in_patch(int /*patch*/, const glm::dvec3& /*x*/) const { return true; }
  virtual double step() const = 0;
};

// The scenes eval knows, with their default shape parameters (the cell
// counts do not change the truth): heightfield, sphere, torus, craters, box,
// slot. `scale` multiplies every length (the kilometre test). Null for an
// unknown name.
std::unique_ptr<TrueSurface> make_true_surface(const std::string& scene, double scale = 1.0);
const std::vector<std::string>& lab_scene_names();

// The front-facing crossing of origin + t dir, t in [0, t_max], nearest to
// t_target (marching from t_target both ways, then bisection). False if none.
bool intersect_true_surface(const TrueSurface& surface, const glm::dvec3& origin, const glm::dvec3& dir,
                            double t_max, double t_target, glm::dvec3& hit, glm::dvec3& normal);

struct EvalOptions {
  int samples = 64;  // of the truth (box filter), not of the bake
  NormalSpace space = NormalSpace::tangent;
  GreenChannel green = GreenChannel::up;
  RayOptions rays;  // cage mode, edge band and resolved front/back of the bake (hit rule and retry unused)
};

struct EvalResult {
  std::size_t texels = 0;         // all texels of the map
  std::size_t covered = 0;        // texels the low UVs cover
  std::size_t without_truth = 0;  // covered, but no sample's ray meets the analytic surface
  AngularError error;             // over the scored texels (covered - without_truth)
  std::string to_text() const;
  std::string to_json() const;
};

// Per covered texel: the expected stored vector and the frame it is compared in.
struct Expected {
  int width = 0, height = 0;
  std::vector<std::uint8_t> scored;         // per texel
  std::vector<glm::vec3> value;             // expected unit vector in the stored space
  std::vector<glm::vec3> frame_t, frame_n;  // MikkTSpace frame of the texel's first sample
  std::vector<float> frame_sign;
  std::size_t covered = 0;
};

// `low` as baked (unit normals, UVs); `cage` the explicit cage or null.
Expected compute_expected(const TrueSurface& surface, const Mesh& low, const Mesh* cage, int width,
                          int height, const EvalOptions& options);
// Binary cache of an Expected, keyed by a string (scene, size, options,
// mesh files): the lab scores many bakes against one truth.
bool save_expected(const std::string& path, const std::string& key, const Expected& expected);
bool load_expected(const std::string& path, const std::string& key, Expected& expected);
EvalResult evaluate(const Expected& expected, const Image& map, const EvalOptions& options);
// The perfect map (float), encoded as the baker encodes; uncovered texels
// hold the background.
Image expected_image(const Expected& expected, const EvalOptions& options);
// round(clamp(v) * levels) / levels, as an integer file would store it.
Image quantize(const Image& image, int levels);

}  // namespace nmbake::scenes
