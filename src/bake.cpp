// The pipeline, in one function: load -> prepare -> raster -> trace ->
// encode -> dilate -> write. Each stage is a free function of its own header;
// this file only wires them, times them and collects their counters.
#include "nmbake/bake.hpp"

#include <charconv>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <string>

#include <sys/resource.h>
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>

namespace nmbake {

bool parse_distance(const std::string& text, Distance& out) {
  if (text == "auto") {
    out = Distance{};
    return true;
  }
  std::string number = text;
  Distance::Kind kind = Distance::Kind::absolute;
  if (!number.empty() && number.back() == '%') {
    number.pop_back();
    kind = Distance::Kind::percent;
  }
  if (number.empty()) return false;
  float value = 0.0f;
  const char* end = number.data() + number.size();
  const auto result = std::from_chars(number.data(), end, value);
  if (result.ec != std::errc() || result.ptr != end || !std::isfinite(value) || value < 0.0f) return false;
  out.kind = kind;
  out.value = value;
  return true;
}

std::string to_string(const Distance& distance) {
  switch (distance.kind) {
    case Distance::Kind::automatic: return "auto";
    case Distance::Kind::percent: return std::to_string(distance.value) + "%";
    case Distance::Kind::absolute: break;
  }
  return std::to_string(distance.value);
}

Status validate_options(const BakeOptions& o) {
  if (o.low_path.empty()) return Status::bad_input("no low mesh given (--low)");
  if (o.high_path.empty()) return Status::bad_input("no high mesh given (--high)");
  if (o.outputs.empty()) return Status::bad_input("no output map given (-o)");
  constexpr int kMaxSize = 32768;
  if (o.width <= 0 || o.height <= 0 || o.width > kMaxSize || o.height > kMaxSize) {
    return Status::bad_input("map size " + std::to_string(o.width) + "x" + std::to_string(o.height) +
                             " is out of range: width and height must be 1 to " + std::to_string(kMaxSize));
  }
  if (!is_supported_sample_count(o.samples)) {
    return Status::bad_input("--samples " + std::to_string(o.samples) + " is not supported: use 1, 4, 16 or 64");
  }
  if (o.padding < 0 || o.padding > 4096) {
    return Status::bad_input("--padding " + std::to_string(o.padding) + " is out of range (0 to 4096)");
  }
  for (const OutputSpec& out : o.outputs) {
    if (!format_matches_extension(out.format, out.path)) {
      return Status::bad_input(out.path + ": format " + to_string(out.format) + " cannot be written to a file with this extension");
    }
    std::filesystem::path folder = std::filesystem::path(out.path).parent_path();
    if (folder.empty()) folder = ".";
    std::error_code ec;
    if (!std::filesystem::is_directory(folder, ec)) {
      return Status::bad_input(out.path + ": the output folder " + folder.string() + " does not exist");
    }
  }
  return Status::ok();
}

namespace {

using Clock = std::chrono::steady_clock;

std::uint64_t peak_rss_bytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<std::uint64_t>(usage.ru_maxrss) * 1024u;
}

class StageTimer {
 public:
  StageTimer(BakeReport& report, const ProgressFn& progress) : report_(report), progress_(progress) {}
  void start(const char* name) {
    name_ = name;
    begin_ = Clock::now();
    if (progress_) progress_(name_, 0.0);
  }
  void stop() {
    const double seconds = std::chrono::duration<double>(Clock::now() - begin_).count();
    report_.stages.push_back({name_, seconds});
    if (progress_) progress_(name_, 1.0);
  }

 private:
  BakeReport& report_;
  const ProgressFn& progress_;
  const char* name_ = "";
  Clock::time_point begin_;
};

float resolve(const Distance& d, float diagonal, float estimated) {
  switch (d.kind) {
    case Distance::Kind::absolute: return d.value;
    case Distance::Kind::percent: return d.value * 0.01f * diagonal;
    case Distance::Kind::automatic: break;
  }
  return estimated;
}

// File normals are normalised; missing ones are computed. The low mesh's
// are averaged over coincident positions, because its vertices are split at
// UV seams and a seam must not become a shading crease.
void prepare_normals(Mesh& mesh, bool is_low, MeshStats& stats) {
  if (mesh.has_normals()) {
    normalize_normals(mesh, stats);
  } else if (is_low) {
    mesh.normals = averaged_normals(mesh, stats);
    stats.normals_computed += mesh.vertex_count();
  } else {
    compute_vertex_normals(mesh, stats);
  }
}

// Per texel: covered, share of missed samples, mean signed hit distance.
Status write_debug_dump(const std::string& prefix, const TexelSamples& samples, const Hits& hits) {
  Image coverage{samples.width, samples.height, 3, {}};
  Image misses = coverage;
  Image distance = coverage;
  const std::size_t texels = static_cast<std::size_t>(samples.width) * samples.height;
  coverage.pixels.assign(texels * 3, 0.0f);
  misses.pixels.assign(texels * 3, 0.0f);
  distance.pixels.assign(texels * 3, 0.0f);
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
      coverage.pixels[t * 3 + ch] = c;
      misses.pixels[t * 3 + ch] = ch == 0 ? m : 0.0f;
      distance.pixels[t * 3 + ch] = d;
    }
  }
  NMBAKE_TRY(write_image(coverage, prefix + "_coverage.png", PixelFormat::png8));
  NMBAKE_TRY(write_image(misses, prefix + "_misses.png", PixelFormat::png8));
  NMBAKE_TRY(write_image(distance, prefix + "_distance.exr", PixelFormat::exr_float));
  return Status::ok();
}

}  // namespace

Status bake(const BakeOptions& o, BakeReport& r, const ProgressFn& progress) {
  const Clock::time_point bake_begin = Clock::now();
  NMBAKE_TRY(validate_options(o));
  r = BakeReport{};
  r.low_path = o.low_path;
  r.high_path = o.high_path;
  r.cage_path = o.cage_path;
  for (const OutputSpec& out : o.outputs) r.outputs.push_back(out.path);
  r.width = o.width;
  r.height = o.height;
  r.samples = o.samples;
  r.threads = tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  StageTimer timer(r, progress);

  // load
  timer.start("load");
  Mesh low, high, cage;
  NMBAKE_TRY(load_mesh(o.low_path, LoadOptions{true, true}, low, r.low_load));
  if (!low.has_uvs()) {
    return Status::bad_input(o.low_path +
                             ": the low mesh has no UV coordinates; a normal map needs a UV layout (export it with UVs)");
  }
  const bool smooth_high = o.high_normals == HighNormals::smooth;
  NMBAKE_TRY(load_mesh(o.high_path, LoadOptions{false, smooth_high}, high, r.high_load));
  const bool use_cage_mesh = !o.cage_path.empty();
  if (use_cage_mesh) {
    LoadStats cage_load;
    NMBAKE_TRY(load_mesh(o.cage_path, LoadOptions{false, false}, cage, cage_load));
    NMBAKE_TRY(check_cage_topology(low, cage, o.cage_path));
  }
  timer.stop();
  r.low_triangles = low.triangle_count();
  r.high_triangles = high.triangle_count();
  r.high_vertices = high.vertex_count();

  // prepare: normals, tangents, cage
  timer.start("prepare");
  prepare_normals(low, true, r.low_mesh);
  if (smooth_high) prepare_normals(high, false, r.high_mesh);
  pad_for_embree(high);
  SurfaceStats surface_stats;
  const LowSurface surface = build_low_surface(low, use_cage_mesh ? &cage : nullptr, o.tangent_basis, surface_stats);
  r.low_mesh.zero_area_triangles += surface_stats.mesh.zero_area_triangles;
  r.low_mesh.zero_length_normals += surface_stats.mesh.zero_length_normals;
  r.tangents = surface_stats.tangents;
  r.low_diagonal = compute_bounds(low).diagonal();
  timer.stop();

  timer.start("build");
  HighScene scene;
  NMBAKE_TRY(HighScene::build(high, o.build_quality, o.ignore_backfaces, scene));
  timer.stop();

  // Ray distances: as given, or estimated by probing the two meshes.
  RayOptions rays;
  rays.cage = use_cage_mesh ? CageMode::mesh : o.cage_mode;
  rays.hit = o.hit;
  rays.ignore_backfaces = o.ignore_backfaces;
  DistanceEstimate estimate;
  const bool need_estimate = o.front.kind == Distance::Kind::automatic || o.back.kind == Distance::Kind::automatic;
  if (need_estimate) {
    timer.start("distances");
    estimate = estimate_distances(scene, surface, r.low_diagonal);
    timer.stop();
    r.distances_estimated = true;
    r.estimate_probes = estimate.probes;
    r.estimate_probe_misses = estimate.probe_misses;
  }
  rays.front = resolve(o.front, r.low_diagonal, estimate.front);
  rays.back = resolve(o.back, r.low_diagonal, estimate.back);
  r.front = rays.front;
  r.back = rays.back;

  timer.start("raster");
  TexelSamples samples;
  rasterize(surface, o.width, o.height, o.samples, samples, r.raster);
  timer.stop();

  timer.start("trace");
  Hits hits;
  trace(scene, surface, samples, rays, hits, r.trace, [&](double f) {
    if (progress) progress("trace", f);
  });
  timer.stop();

  timer.start("encode");
  EncodeOptions encode_options;
  encode_options.space = o.space;
  encode_options.green = o.green;
  encode_options.high_normals = o.high_normals;
  encode_options.tangent_encode = o.tangent_encode;
  Image image;
  encode(surface, samples, high, hits, encode_options, image, r.encode);
  timer.stop();

  if (!o.debug_dump_prefix.empty()) NMBAKE_TRY(write_debug_dump(o.debug_dump_prefix, samples, hits));

  timer.start("dilate");
  std::vector<std::uint8_t> coverage = samples.coverage;
  dilate(image, coverage, o.padding, r.dilate);
  timer.stop();

  // Every output is written at once (each writer is single-threaded).
  timer.start("write");
  std::vector<Status> written(o.outputs.size());
  tbb::parallel_for(std::size_t{0}, o.outputs.size(),
                    [&](std::size_t i) { written[i] = write_image(image, o.outputs[i].path, o.outputs[i].format); });
  for (const Status& s : written) NMBAKE_TRY(s);
  timer.stop();

  r.total_seconds = std::chrono::duration<double>(Clock::now() - bake_begin).count();
  r.peak_rss_bytes = peak_rss_bytes();
  return Status::ok();
}

}  // namespace nmbake
