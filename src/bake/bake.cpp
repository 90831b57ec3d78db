// The pipeline, in one function: load -> prepare -> raster -> trace ->
// encode -> dilate -> write. Each stage is a free function of its own header;
// this file only wires them, times them and collects their counters.
#include "nmbake/bake.hpp"

#include "base/huge_pages.hpp"
#include "nmbake/budget.hpp"
#include "nmbake/maps.hpp"
#include "nmbake/task.hpp"
#include "nmbake/udim.hpp"

#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <chrono>
#include <cmath>
#include <algorithm>
#include <filesystem>
#include <memory>
#include <string>

#include <sys/resource.h>
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>

namespace nmbake {

namespace {

std::string number_text(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", value);
  return text;
}

// Resolved distances against the low mesh's diagonal (kMaxDistanceDiagonals).
// A zero diagonal (every low vertex in one place) has only kMaxDistance.
Status check_distance(const char* name, const Distance& d, float diagonal) {
  const double limit = static_cast<double>(kMaxDistanceDiagonals) * diagonal;
  if (d.kind != Distance::Kind::absolute || diagonal <= 0.0f || d.value <= limit) return Status::ok();
  return Status::bad_input(std::string(name) + " distance " + number_text(d.value) + " is out of range: at most " +
                           number_text(kMaxDistanceDiagonals) + " times the low mesh's diagonal " +
                           number_text(diagonal) + " = " + number_text(limit) + " scene units");
}

// The map set's options (maps.hpp).
Status validate_map_set(const BakeOptions& o) {
  if (o.maps.empty()) return Status::bad_input("no map to bake (--map)");
  for (const MapKind map : o.maps) {
    if (!map_traits(map).implemented) return Status::bad_input(std::string("--map ") + to_string(map) + ": not implemented yet");
  }
  NMBAKE_TRY(check_map_tokens(o.outputs, o.maps));
  for (const MapOutput& out : map_outputs(o)) {
    if (const Status target = check_output_target(out.path); !target) return Status::bad_input(target.message());
  }
  const auto check_range = [](const char* name, float value) {
    if (!(value >= 0.0f) || !std::isfinite(value)) {
      return Status::bad_input(std::string(name) + " " + number_text(value) + " is out of range: a number > 0, or auto");
    }
    return Status::ok();
  };
  NMBAKE_TRY(check_range("--height-range", o.height_range));
  NMBAKE_TRY(check_range("--curvature-range", o.curvature_range));
  for (const auto& [name, rays] : {std::pair{"--ao-rays", o.ao_rays}, std::pair{"--thickness-rays", o.thickness_rays}}) {
    if (rays < 1 || rays > kMaxOcclusionRays) {
      return Status::bad_input(std::string(name) + " " + std::to_string(rays) + " is out of range (1 to " +
                               std::to_string(kMaxOcclusionRays) + ")");
    }
  }
  for (const auto& [name, d] :
       {std::pair{"--ao-distance", o.ao_distance}, std::pair{"--thickness-distance", o.thickness_distance}}) {
    if (d.kind != Distance::Kind::automatic && !(d.value > 0.0f)) {
      return Status::bad_input(std::string(name) + " " + to_string(d) + " is out of range: a distance > 0, N% or auto");
    }
    if (d.kind == Distance::Kind::absolute && !(d.value <= kMaxDistance)) {
      return Status::bad_input(std::string(name) + " " + number_text(d.value) + " is out of range: at most " +
                               number_text(kMaxDistance) + " scene units");
    }
    if (d.kind == Distance::Kind::percent && !(d.value <= 100.0f * kMaxDistanceDiagonals)) {
      return Status::bad_input(std::string(name) + " " + number_text(d.value) + "% is out of range: at most " +
                               number_text(100.0f * kMaxDistanceDiagonals) + "% of the low mesh's diagonal");
    }
  }
  if (o.adaptive && (o.maps.size() != 1 || o.maps.front() != MapKind::normal)) {
    return Status::bad_input("--samples adaptive bakes the normal map alone; the map set (" + map_list_text(o.maps) +
                             ") needs a fixed sample count (1, 4, 16 or 64)");
  }
  return Status::ok();
}

}  // namespace

Status write_map_files(MapSet& maps, const std::vector<MapOutput>& files, bool dither) {
  std::vector<Status> written(files.size());
  tbb::parallel_for(std::size_t{0}, files.size(), [&](std::size_t i) {
    const MapOutput& out = files[i];
    WriteOptions options;
    options.dither = dither;
    maps.integer_mapping(out.map, options.scale, options.offset);
    written[i] = write_image(maps.image(out.map), out.path, out.format, options);
  });
  for (const Status& s : written) NMBAKE_TRY(s);
  return Status::ok();
}

std::vector<MapReport> map_file_reports(const MapSet& maps, const std::vector<MapOutput>& files, int tile) {
  std::vector<MapReport> reports = maps.reports(tile);
  for (MapReport& m : reports) {
    for (const MapOutput& out : files) {
      if (out.map == m.map) m.outputs.push_back(out.path);
    }
  }
  return reports;
}

Status check_map_tokens(const std::vector<OutputSpec>& outputs, const std::vector<MapKind>& maps) {
  if (maps.size() <= 1) return Status::ok();
  for (const OutputSpec& out : outputs) {
    if (!has_map_token(out.path)) {
      return Status::bad_input(printable_text(out.path) + ": " + std::to_string(maps.size()) +
                               " maps are baked (" + map_list_text(maps) + "): the output path needs the " +
                               kMapToken + " token, e.g. asset_" + kMapToken + ".png");
    }
  }
  return Status::ok();
}

std::vector<MapOutput> map_outputs(const BakeOptions& o) { return map_outputs(o.outputs, o.maps); }

std::vector<MapOutput> map_outputs(const std::vector<OutputSpec>& outputs, const std::vector<MapKind>& maps) {
  std::vector<MapOutput> out;
  for (const OutputSpec& spec : outputs) {
    for (const MapKind map : maps) {
      MapOutput m;
      m.path = map_path(spec.path, map);
      m.format = map_format(map, spec.format, spec.format_given, spec.path);
      m.map = map;
      out.push_back(std::move(m));
    }
  }
  return out;
}

Status validate_option_values(const BakeOptions& o) {
  constexpr int kMaxSize = 32768;
  if (o.width <= 0 || o.height <= 0 || o.width > kMaxSize || o.height > kMaxSize) {
    return Status::bad_input("map size " + std::to_string(o.width) + "x" + std::to_string(o.height) +
                             " is out of range: width and height must be 1 to " + std::to_string(kMaxSize));
  }
  if (o.adaptive) {
    const int m = o.adaptive_options.max_samples;
    if (m != 4 && m != 16 && m != 64) {
      return Status::bad_input("--adaptive-max " + std::to_string(m) + " is not supported: use 4, 16 or 64");
    }
    const AdaptiveOptions& a = o.adaptive_options;
    for (const float t : {a.normal_threshold, a.depth_threshold, a.border_threshold, a.spread_threshold}) {
      if (!(t >= 0.0f) || !std::isfinite(t))
        return Status::bad_input("adaptive thresholds must be finite and >= 0");
    }
  } else if (!is_supported_sample_count(o.samples)) {
    return Status::bad_input("--samples " + std::to_string(o.samples) +
                             " is not supported: use 1, 4, 16 or 64");
  }
  // Against the map size only when an unwrap happens (bake()): a small map
  // of a mesh with UVs must not be refused for a gutter it never uses.
  if (o.unwrap_gutter < 0) {
    return Status::bad_input("unwrap gutter " + std::to_string(o.unwrap_gutter) + " is out of range (0 to size / 4)");
  }
  const auto check_limit = [](const char* name, const Distance& d) {
    if (d.kind == Distance::Kind::absolute && !(d.value <= kMaxDistance)) {
      return Status::bad_input(std::string(name) + " distance " + number_text(d.value) +
                               " is out of range: at most " + number_text(kMaxDistance) + " scene units");
    }
    if (d.kind == Distance::Kind::percent && !(d.value <= 100.0f * kMaxDistanceDiagonals)) {
      return Status::bad_input(std::string(name) + " distance " + number_text(d.value) +
                               "% is out of range: at most " + number_text(100.0f * kMaxDistanceDiagonals) +
                               "% of the low mesh's diagonal");
    }
    return Status::ok();
  };
  if (!(o.edge_band >= 0.0f && o.edge_band <= 100.0f)) {
    return Status::bad_input("--edge-band " + number_text(o.edge_band) + " is out of range (0 to 100)");
  }
  NMBAKE_TRY(check_limit("front", o.front));
  NMBAKE_TRY(check_limit("back", o.back));
  if (o.padding < 0 || o.padding > 4096) {
    return Status::bad_input("--padding " + std::to_string(o.padding) + " is out of range (0 to 4096)");
  }
  if (o.uv_set < 0 || o.uv_set > 7) {
    return Status::bad_input("--uv-set " + std::to_string(o.uv_set) + " is out of range (0 to 7)");
  }
  if (o.groups_per_scene < 0 || o.groups_per_scene > 32) {
    return Status::bad_input("--groups-per-scene " + std::to_string(o.groups_per_scene) +
                             " is out of range (0 to 32)");
  }
  return Status::ok();
}

Status validate_options(const BakeOptions& o) {
  if (o.low_path.empty()) return Status::bad_input("no low mesh given (--low)");
  if (o.high_path.empty()) return Status::bad_input("no high mesh given (--high)");
  if (o.outputs.empty()) return Status::bad_input("no output map given (-o)");
  NMBAKE_TRY(validate_option_values(o));
  for (const OutputSpec& out : o.outputs) {
    // The file system would see the path cut at the NUL: another file.
    if (out.path.find('\0') != std::string::npos) {
      return Status::bad_input(printable_text(out.path) + ": the output path holds a NUL byte");
    }
    if (const Status target = check_output_target(out.path); !target) return Status::bad_input(target.message());
    if (!format_matches_extension(out.format, out.path)) {
      return Status::bad_input(out.path + ": format " + to_string(out.format) + " cannot be written to a file with this extension");
    }
    std::filesystem::path folder = std::filesystem::path(out.path).parent_path();
    if (folder.empty()) folder = ".";
    std::error_code ec;
    if (!std::filesystem::is_directory(folder, ec)) {
      return Status::bad_input(out.path + ": the output folder " + folder.string() + " does not exist");
    }
    // TIFF needs the OpenImageIO module: known before the bake, not after.
    if (const Status writer = check_image_writer(out.format); !writer) {
      return Status::internal(out.path + ": " + writer.message());  // names the output once
    }
  }
  return validate_map_set(o);
}

namespace {

// `path` for a message: a path from a job file may hold any byte.
std::string shown(const std::string& path) { return printable_text(path); }

Status check_mesh_input(const char* what, const std::string& path) {
  if (path.empty()) return Status::bad_input(std::string("the ") + what + " mesh path is empty");
  if (path.find('\0') != std::string::npos) {
    return Status::bad_input(shown(path) + ": the " + what + " mesh path holds a NUL byte");
  }
  std::string extension = std::filesystem::path(path).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (!mesh_extension_supported(path)) {
    return Status::bad_input(shown(path) + ": unknown mesh format '" + shown(extension) + "' (expected " +
                             supported_mesh_extensions() + ")");
  }
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) {
    return Status::bad_input(shown(path) + ": the " + what + " mesh does not exist");
  }
  // A FIFO would block and a device (a link to /dev/zero) never ends.
  if (!std::filesystem::is_regular_file(status)) {
    return Status::bad_input(shown(path) + ": the " + what + " mesh is not a regular file");
  }
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (!file) return Status::bad_input(shown(path) + ": cannot open the " + what + " mesh: " + std::strerror(errno));
  char head[4096];
  const std::size_t got = std::fread(head, 1, sizeof head, file);
  std::fclose(file);
  const std::string_view bytes(head, got);
  if (got == 0) return Status::bad_input(shown(path) + ": the " + what + " mesh is empty");
  if (extension == ".ply" && bytes.substr(0, 3) != "ply") {
    return Status::bad_input(shown(path) + ": not a PLY file (it does not start with \"ply\")");
  }
  if (extension == ".glb" && bytes.substr(0, 4) != "glTF") {
    return Status::bad_input(shown(path) + ": not a binary glTF file (it does not start with \"glTF\")");
  }
  if (extension == ".obj" && bytes.find('\0') != std::string_view::npos) {
    return Status::bad_input(shown(path) + ": not an OBJ file (a NUL byte in its first " + std::to_string(got) +
                             " bytes: binary data)");
  }
  return Status::ok();
}

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
  // A stage run several times (once per band) adds up under one name.
  void stop(bool report_done = true) {
    const double seconds = std::chrono::duration<double>(Clock::now() - begin_).count();
    for (StageTime& st : report_.stages) {
      if (st.name == name_) {
        st.seconds += seconds;
        if (progress_ && report_done) progress_(name_, 1.0);
        return;
      }
    }
    report_.stages.push_back({name_, seconds});
    if (progress_ && report_done) progress_(name_, 1.0);
  }
  void start_quietly(const char* name) {
    name_ = name;
    begin_ = Clock::now();
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

// High normals: the file's, normalised, or area-weighted ones.
void prepare_high_normals(Mesh& mesh, MeshStats& stats) {
  if (mesh.has_normals()) {
    normalize_normals(mesh, stats);
  } else {
    compute_vertex_normals(mesh, stats);
  }
}

// Per texel: covered, share of missed samples, mean signed hit distance;
// filled band by band.
struct DebugImages {
  Image coverage, misses, distance, refined;
  bool adaptive = false;
  DebugImages(int width, int height, bool adaptive_bake) : adaptive(adaptive_bake) {
    for (Image* image : {&coverage, &misses, &distance, &refined}) {
      image->width = width;
      image->height = height;
      image->channels = 3;
      image->pixels.assign(static_cast<std::size_t>(width) * height * 3, 0.0f);
    }
  }
  void add_band(const TexelSamples& samples, const Hits& hits) {
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
  // Adaptive sampling: the texels a level chose (band indices of the band
  // starting at image row `row_begin`), drawn with `value` (the last level
  // white).
  void add_refined(int row_begin, const std::vector<std::uint32_t>& texels, float value) {
    const std::size_t offset = static_cast<std::size_t>(row_begin) * refined.width;
    for (const std::uint32_t t : texels) {
      for (int ch = 0; ch < 3; ++ch) refined.pixels[(offset + t) * 3 + ch] = value;
    }
  }
  Status write(const std::string& prefix) const {
    if (adaptive) NMBAKE_TRY(write_image(refined, prefix + "_refined.png", PixelFormat::png8));
    NMBAKE_TRY(write_image(coverage, prefix + "_coverage.png", PixelFormat::png8));
    NMBAKE_TRY(write_image(misses, prefix + "_misses.png", PixelFormat::png8));
    NMBAKE_TRY(write_image(distance, prefix + "_distance.exr", PixelFormat::exr_float));
    return Status::ok();
  }
};

}  // namespace

// About 1M samples a band, so the per-sample arrays (28 bytes a sample, ~28
// MB) stay in the last-level cache between raster, trace and encode, and a
// bake first-touches little fresh memory (slow on these virtual machines,
// BENCHMARKS.md). With the trace no longer split into progress batches
// without a listener, a band costs little: at 2048^2 16 spp, 64 bands of 1M
// bake as fast as 16 of 4M, with 84 MB less peak memory.
namespace {

// How bake() loads the low mesh; check_bake_low_mesh() loads it the same way.
LoadOptions low_load_options(const BakeOptions& o) {
  LoadOptions options{true, true};
  options.uv_set = o.uv_set;
  options.keep_tangents = o.tangent_basis == TangentBasis::file;
  return options;
}

bool bakes_udim_tiles(const BakeOptions& o) {
  return std::any_of(o.outputs.begin(), o.outputs.end(),
                     [](const OutputSpec& out) { return has_udim_token(out.path); });
}

}  // namespace

Status check_bake_low_mesh(const BakeOptions& o) {
  Mesh low;
  LoadStats stats;
  NMBAKE_TRY(load_mesh(o.low_path, low_load_options(o), low, stats));
  NMBAKE_TRY(check_low_parts(low, o.match, o.low_path));
  // A low mesh without UVs is unwrapped into [0, 1]^2: one tile, whatever
  // the outputs say.
  if (low.has_uvs()) {
    std::vector<int> tiles;
    NMBAKE_TRY(find_udim_tiles(low, o.low_path, bakes_udim_tiles(o), tiles));
  }
  return Status::ok();
}

Status check_bake_inputs(const BakeOptions& o) {
  NMBAKE_TRY(check_mesh_input("low", o.low_path));
  NMBAKE_TRY(check_mesh_input("high", o.high_path));
  if (!o.cage_path.empty()) NMBAKE_TRY(check_mesh_input("cage", o.cage_path));
  if (o.debug_dump_prefix.find('\0') != std::string::npos) {
    return Status::bad_input(shown(o.debug_dump_prefix) + ": the debug-dump path holds a NUL byte");
  }
  return Status::ok();
}


namespace {

// What every UDIM tile of a bake shares: the prepared meshes, the scene and
// the rays.
struct Prepared {
  const BakeOptions& options;
  const Mesh& high;
  const HighScene& scene;
  const RayOptions& rays;
  MapSettings maps;  // the map set, with the normal map's encode options
};

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
               std::vector<std::uint8_t>& coverage, const EncodeOptions& encode_options, DebugImages* debug)
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

  void run(int first_row, int last_row, StageTimer& timer, const ProgressFn& progress,
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
  void first_pass(Band& band, int row_begin, int row_end, bool counted) {
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
    encode(surface_, band.samples, p_.high, band.hits, band_encode, band.image,
           counted ? r_.encode : encoded);
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
    r_.raster.covered_texels += raster.covered_texels;
    r_.raster.border_samples += raster.border_samples;
    r_.raster.overlapping_samples += raster.overlapping_samples;
    r_.raster.degenerate_uv_triangles = raster.degenerate_uv_triangles;
    add(r_.trace, traced);
    r_.adaptive.first_pass_rays += traced.rays;
  }

  // `texels` (band indices, ascending) with level `level`'s pattern, in
  // chunks of about a band's samples, each value written over the one
  // before; the texels the next level takes go on to it chunk by chunk.
  void refine_level(std::size_t level, const std::vector<std::uint32_t>& texels, int row_begin, int row_end,
                    int first_row) {
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

  static void add(TraceStats& to, const TraceStats& from) {
    to.rays += from.rays;
    to.samples += from.samples;
    to.hits += from.hits;
    to.misses += from.misses;
    to.ray_fallbacks += from.ray_fallbacks;
  }

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

// raster -> trace -> [occlusion rays] -> encode (every map of the set),
// band of rows by band of rows, then dilate and write, for one map (a UDIM
// tile: `surface` has the tile's UVs shifted into [0, 1]^2). The per-sample
// arrays are reused and bounded, so a 16384^2 map bakes in the memory of a
// small one. Bands change nothing in the result: raster tiles and ray
// packets both start on band rows.
// Rows [first_row, last_row) of the map (all of it, or a tile's: then the
// image and coverage hold only those rows, and nothing is dilated or
// written: `tile` gets them).
Status bake_tile(const Prepared& p, const LowSurface& surface, const std::vector<MapOutput>& outputs,
                 const std::string& debug_prefix, BakeReport& r, StageTimer& timer, const ProgressFn& progress,
                 std::uint64_t& covered_texels, int first_row, int last_row, int udim_tile, TileData* tile) {
  const BakeOptions& o = p.options;
  const int rows = last_row - first_row;
  MapSet maps(p.maps, o.width, first_row, last_row);
  std::vector<std::uint8_t> coverage(static_cast<std::size_t>(o.width) * rows, 0);
  std::unique_ptr<DebugImages> debug;
  if (!debug_prefix.empty()) debug = std::make_unique<DebugImages>(o.width, o.height, o.adaptive);
  TexelSamples samples;
  Hits hits;
  covered_texels = 0;
  if (o.adaptive) {
    // The normal map alone (validate_options); its image holds rows from first_row.
    EncodeOptions encode_options = p.maps.encode;
    encode_options.out_row_begin = first_row;
    AdaptiveRows(p, surface, r, maps.image(MapKind::normal), coverage, encode_options, debug.get())
        .run(first_row, last_row, timer, progress, covered_texels);
  } else {
    const int rows_per_band = band_rows(o.width, o.height, o.samples, o.band_samples);
    for (int row = first_row; row < last_row; row += rows_per_band) {
      const int row_end = std::min(row + rows_per_band, last_row);
      timer.start_quietly("raster");
      RasterStats band_raster;
      rasterize(surface, o.width, o.height, o.samples, samples, band_raster, row, row_end);
      covered_texels += band_raster.covered_texels;
      r.raster.covered_texels += band_raster.covered_texels;
      r.raster.border_samples += band_raster.border_samples;
      r.raster.overlapping_samples += band_raster.overlapping_samples;
      r.raster.degenerate_uv_triangles = band_raster.degenerate_uv_triangles;  // the same in every band
      std::copy(samples.coverage.begin(), samples.coverage.end(),
                coverage.begin() + static_cast<std::ptrdiff_t>(row - first_row) * o.width);
      timer.stop(false);

      timer.start_quietly("trace");
      // Without a listener trace() gets none: it then runs each band as one
      // parallel loop instead of 100 batches with a barrier each.
      std::function<void(double)> trace_progress;
      if (progress) {
        trace_progress = [&](double f) { progress("trace", (row + f * (row_end - row)) / o.height); };
      }
      trace(p.scene, surface, samples, p.rays, hits, r.trace, trace_progress);
      timer.stop(false);

      if (maps.needs_rays()) {
        // AO, bent normals, thickness: their own rays from this band's hits.
        timer.start_quietly("occlusion");
        maps.trace_rays(p.scene, p.high, surface, samples, hits);
        timer.stop(false);
        if (progress) progress("occlusion", static_cast<double>(row_end) / o.height);
      }

      timer.start_quietly("encode");
      maps.encode_band(surface, samples, p.high, hits, r.encode);
      timer.stop(false);
      if (debug) debug->add_band(samples, hits);
    }
  }
  if (debug) NMBAKE_TRY(debug->write(debug_prefix));
  if (tile != nullptr) {
    // Every map's raw texels and what its bands counted: the merge finishes them.
    for (const MapKind map : p.maps.maps) tile->texels.push_back(std::move(maps.image(map).pixels));
    tile->counts = maps.counts();
    tile->coverage = std::move(coverage);
    return Status::ok();
  }

  timer.start("dilate");
  maps.finish(coverage, o.padding, r.dilate);
  timer.stop();

  timer.start("write");
  NMBAKE_TRY(write_map_files(maps, outputs, o.dither));
  timer.stop();
  for (MapReport& m : map_file_reports(maps, outputs, udim_tile)) r.map_reports.push_back(std::move(m));
  return Status::ok();
}

}  // namespace

Status bake(const BakeOptions& o, BakeReport& r, const ProgressFn& progress) {
  const Clock::time_point bake_begin = Clock::now();
  NMBAKE_TRY(validate_options(o));
  const bool tiled = o.tile_count > 0;
  if (tiled) {
    if (o.tile_index < 0 || o.tile_index >= o.tile_count || o.tile_count > 4096) {
      return Status::bad_input("tile " + std::to_string(o.tile_index + 1) + "/" + std::to_string(o.tile_count) +
                               " does not exist (1/N to N/N, N up to 4096)");
    }
    if (o.tile_path.empty()) return Status::bad_input("a tile bake needs a tile file to write");
    for (const OutputSpec& out : o.outputs) {
      if (has_udim_token(out.path)) return Status::bad_input(out.path + ": <UDIM> maps cannot be baked in tiles yet");
    }
  }
  r = BakeReport{};
  r.low_path = o.low_path;
  r.high_path = o.high_path;
  r.cage_path = o.cage_path;
  for (const OutputSpec& out : o.outputs) r.outputs.push_back(out.path);
  r.width = o.width;
  r.height = o.height;
  r.samples = o.samples;
  r.preset = o.preset;
  r.green = o.green;
  r.decode = o.decode;
  r.dither = o.dither;
  r.threads = tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  StageTimer timer(r, progress);

  // The map's own buffers first (no file needed), then with the meshes'
  // sizes once they are loaded, before the BVH and the map are allocated.
  NMBAKE_TRY(check_bake_memory(o, MeshSize{}, MeshSize{}));

  // load
  timer.start("load");
  Mesh low, high, cage;
  NMBAKE_TRY(load_mesh(o.low_path, low_load_options(o), low, r.low_load));
  const bool smooth_high = o.high_normals == HighNormals::smooth;
  const auto wants = [&](MapKind map) { return std::find(o.maps.begin(), o.maps.end(), map) != o.maps.end(); };
  LoadOptions high_options{false, smooth_high};
  high_options.keep_colors = wants(MapKind::vertex_color);
  NMBAKE_TRY(load_mesh(o.high_path, high_options, high, r.high_load));
  if (high_options.keep_colors && !high.has_colors()) {
    return Status::bad_input(
        o.high_path +
        ": --map vertex-color, but the high mesh has no vertex colours (read from "
        "PLY red/green/blue properties, glTF COLOR_0, FBX and Collada vertex colours, and OBJ "
        "\"v x y z r g b\" lines)");
  }
  if (wants(MapKind::id) && o.id_source == IdSource::material && !high.has_named_materials()) {
    return Status::bad_input(o.high_path +
                             ": --map id with --id-source material, but the high mesh has no named "
                             "materials (OBJ usemtl, glTF primitive materials, FBX and Collada materials)");
  }
  const bool use_cage_mesh = !o.cage_path.empty();
  if (use_cage_mesh) {
    LoadStats cage_load;
    NMBAKE_TRY(load_mesh(o.cage_path, LoadOptions{false, false}, cage, cage_load));
    NMBAKE_TRY(order_cage_by_parts(low, o.match, o.cage_path, cage));
    NMBAKE_TRY(check_cage_topology(low, cage, o.cage_path));
  }
  // Every derived value (diagonal, normals, ray origins) stays finite only
  // within these bounds; Embree aborts on a ray that is not.
  NMBAKE_TRY(check_coordinate_range(low, o.low_path));
  NMBAKE_TRY(check_coordinate_range(high, o.high_path));
  if (use_cage_mesh) NMBAKE_TRY(check_coordinate_range(cage, o.cage_path));
  NMBAKE_TRY(check_bake_memory(o, MeshSize{low.vertex_count(), low.triangle_count()},
                                MeshSize{high.vertex_count(), high.triangle_count()}));
  {
    const float diagonal = compute_bounds(low).diagonal();
    NMBAKE_TRY(check_distance("front", o.front, diagonal));
    NMBAKE_TRY(check_distance("back", o.back, diagonal));
  }
  timer.stop();
  // Parts into groups before anything is baked: a naming mistake is found in
  // a second, not after the unwrap.
  BakeGroups groups;
  NMBAKE_TRY(match_parts(low, high, o.match, o.low_path, o.high_path, groups));
  const bool udim = bakes_udim_tiles(o);
  if (!low.has_uvs()) {
    const int side = std::min(o.width, o.height);
    if (o.unwrap_gutter > side / 4) {
      return Status::bad_input(o.low_path + ": the low mesh has no UVs and a " + std::to_string(o.width) + "x" +
                               std::to_string(o.height) + " map is too small to unwrap it into: unwrap gutter " +
                               std::to_string(o.unwrap_gutter) + " is out of range (0 to size / 4 = " +
                               std::to_string(side / 4) + ")");
    }
    timer.start("unwrap");
    // No UV layout: make one; the map is useless without the mesh, so it is
    // written beside the map (in the write stage, with the maps). The unwrap
    // keeps the triangle order, so the groups stay valid.
    UnwrapOptions unwrap_options;
    unwrap_options.pack.resolution = std::min(o.width, o.height);
    unwrap_options.pack.gutter = o.unwrap_gutter;
    Mesh unwrapped;
    const Status s = unwrap_mesh(low, unwrap_options, unwrapped, r.unwrap);
    if (!s) return Status::bad_input(o.low_path + ": the low mesh has no UVs; " + s.message());
    low = std::move(unwrapped);
    r.unwrapped = true;
    const std::filesystem::path first(udim_path(map_path(o.outputs.front().path, o.maps.front()), 1001));
    r.unwrapped_low_path = (first.parent_path() / (first.stem().string() + "_low_uv.obj")).string();
    timer.stop();
  }
  if (o.tangent_basis == TangentBasis::file && !low.has_tangents()) {
    // Checked after unwrap: a mesh unwrapped here has no file tangents either.
    return Status::bad_input(o.low_path + ": --tangents file, but the low mesh has no tangents (glTF TANGENT or FBX "
                             "tangents on every part, and UVs)");
  }
  std::vector<int> tiles;
  NMBAKE_TRY(find_udim_tiles(low, o.low_path, udim, tiles));
  r.low_triangles = low.triangle_count();
  r.high_triangles = high.triangle_count();
  r.high_vertices = high.vertex_count();

  // prepare: normals, tangents, cage, groups
  timer.start("prepare");
  prepare_low_normals(low, r.low_mesh);
  if (smooth_high) prepare_high_normals(high, r.high_mesh);
  // The map set's data from the whole high mesh (bounds, vertex curvature,
  // parts or materials), before groups reorder its triangles.
  MapMeshData map_mesh;
  prepare_map_mesh(high, o.maps, o.id_source, groups, map_mesh);
  r.curvature_degenerate_triangles = map_mesh.curvature.degenerate_triangles;
  r.curvature_isolated_vertices = map_mesh.curvature.isolated_vertices;
  r.id_source = map_mesh.id_source;
  r.id_names = map_mesh.ids;
  SceneGroups scene_groups;
  if (groups.grouped()) {
    // Normals come from the whole high mesh first; then each group's
    // triangles become one range of the index buffer (unused parts dropped).
    high.indices = group_high_indices(high, groups, scene_groups.first_triangle);
    // The ranges no longer match the triangles (the map set took what it
    // needs of them above).
    high.parts.clear();
    high.materials.clear();
    scene_groups.groups_per_scene = o.groups_per_scene;
  }
  r.high_triangles_used = high.triangle_count();
  pad_for_embree(high);
  SurfaceStats surface_stats;
  LowSurface surface = build_low_surface(low, use_cage_mesh ? &cage : nullptr, o.tangent_basis, surface_stats);
  surface.group = groups.low_group;
  r.low_mesh.zero_area_triangles += surface_stats.mesh.zero_area_triangles;
  r.low_mesh.zero_length_normals += surface_stats.mesh.zero_length_normals;
  r.tangents = surface_stats.tangents;
  r.low_diagonal = compute_bounds(low).diagonal();
  timer.stop();

  timer.start("build");
  HighScene scene;
  NMBAKE_TRY(HighScene::build(high, o.build_quality, o.ignore_backfaces, scene, o.bvh_memory,
                              groups.grouped() ? &scene_groups : nullptr));
  r.compact_bvh = scene.compact();
  r.scenes = scene.scene_count();
  timer.stop();

  // Ray distances: as given, or estimated by probing the two meshes (each
  // group its own).
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
  rays.edge_band = o.edge_band;
  const bool retry = o.retry_misses == BakeOptions::Retry::on ||
                     (o.retry_misses == BakeOptions::Retry::automatic && !use_cage_mesh &&
                      o.front.kind == Distance::Kind::automatic && o.back.kind == Distance::Kind::automatic);
  rays.retry_reach = retry ? kProbeReach * r.low_diagonal : 0.0f;
  r.cage_mode = to_string(rays.cage);
  r.edge_band = rays.cage == CageMode::banded ? rays.edge_band : 0.0f;
  r.retry_reach = rays.retry_reach;
  r.front = rays.front;
  r.back = rays.back;
  if (need_estimate) {
    NMBAKE_CHECK(estimate.groups.size() == std::max<std::size_t>(groups.groups.size(), 1),
                 "an estimate per group");
  }
  for (std::size_t g = 0; g < groups.groups.size(); ++g) {
    const GroupDistances e = need_estimate ? estimate.groups[g] : GroupDistances{};
    rays.groups.push_back({resolve(o.front, r.low_diagonal, e.front), resolve(o.back, r.low_diagonal, e.back)});
    r.groups.push_back({groups.groups[g], rays.groups.back().front, rays.groups.back().back});
  }
  r.unused_high_parts = groups.unused_high_parts;
  if (rays.cage == CageMode::banded) prepare_edge_band(surface, edge_band_reach(rays));

  Prepared prepared{o, high, scene, rays, MapSettings{}};
  MapSettings& map_settings = prepared.maps;
  map_settings.maps = o.maps;
  map_settings.encode.space = o.space;
  map_settings.encode.green = o.green;
  map_settings.encode.high_normals = o.high_normals;
  map_settings.encode.tangent_encode = o.tangent_encode;
  map_settings.encode.decode = o.decode;
  map_settings.height_range = o.height_range;
  map_settings.curvature_range = o.curvature_range;
  const float auto_map_distance = kAutoMapDistancePercent * 0.01f * r.low_diagonal;
  map_settings.occlusion.rays = o.ao_rays;
  map_settings.occlusion.distance = resolve(o.ao_distance, r.low_diagonal, auto_map_distance);
  map_settings.occlusion.bent = map_settings.has(MapKind::bent_normal);
  map_settings.thickness.rays = o.thickness_rays;
  map_settings.thickness.distance = resolve(o.thickness_distance, r.low_diagonal, auto_map_distance);
  map_mesh.apply(map_settings);
  r.maps = o.maps;
  const std::vector<MapOutput> map_files = map_outputs(o);
  const std::vector<glm::vec2> file_uvs = udim ? surface.uv : std::vector<glm::vec2>{};
  r.outputs.clear();
  for (const int tile : tiles) {
    BakeReport::Tile done;
    done.tile = tile;
    std::vector<MapOutput> outputs = map_files;
    for (MapOutput& out : outputs) {
      out.path = udim_path(out.path, tile);
      done.outputs.push_back(out.path);
      r.outputs.push_back(out.path);
    }
    std::string debug_prefix = o.debug_dump_prefix;
    if (udim) {
      // The tile's UVs into [0, 1]^2 (exact: whole-number shifts).
      const glm::vec2 offset = udim_offset(tile);
      for (std::size_t i = 0; i < file_uvs.size(); ++i) surface.uv[i] = file_uvs[i] - offset;
      if (!debug_prefix.empty()) debug_prefix += "." + std::to_string(tile);
    }
    if (tiled) {
      TileData rows;
      NMBAKE_TRY(bake_key(o, rows.key));
      r.key = rows.key.hex();
      rows.width = o.width;
      rows.height = o.height;
      tile_rows(o.height, o.tile_index, o.tile_count, rows.row_begin, rows.row_end);
      rows.index = o.tile_index;
      rows.count = o.tile_count;
      rows.padding = o.padding;
      rows.dither = o.dither;
      rows.outputs = o.outputs;  // <MAP> kept: the merge names each map's file as the bake does
      rows.maps = map_settings;
      rows.maps.vertex_curvature = nullptr;  // the mesh data is encoding's alone
      rows.maps.triangle_id = nullptr;
      rows.maps.id_colors = nullptr;
      NMBAKE_TRY(bake_tile(prepared, surface, outputs, debug_prefix, r, timer, progress, done.covered_texels,
                           rows.row_begin, rows.row_end, tile, &rows));
      timer.start("write");
      NMBAKE_TRY(write_tile(o.tile_path, rows));
      timer.stop();
      r.tile_index = rows.index;
      r.tile_count = rows.count;
      r.tile_row_begin = rows.row_begin;
      r.tile_row_end = rows.row_end;
      r.tile_path = o.tile_path;
      r.outputs = {o.tile_path};
      done.outputs = {o.tile_path};
    } else {
      NMBAKE_TRY(bake_tile(prepared, surface, outputs, debug_prefix, r, timer, progress, done.covered_texels, 0,
                           o.height, tile, nullptr));
    }
    r.tiles.push_back(std::move(done));
  }
  if (r.unwrapped) {
    timer.start("write");
    NMBAKE_TRY(save_mesh(r.unwrapped_low_path, low));
    timer.stop();
  }

  r.total_seconds = std::chrono::duration<double>(Clock::now() - bake_begin).count();
  r.peak_rss_bytes = peak_rss_bytes();
  return Status::ok();
}

}  // namespace nmbake
