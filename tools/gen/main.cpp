// nmbake-gen: writes the generated scenes (scenes.hpp) as a low .obj and a
// high .ply, for the demo, the lab and regression bakes.
//
//   nmbake-gen moon        --out-dir DIR [--high-cells N] [--low-cells N] [--craters N] [--seed S] [--radius
//   R] nmbake-gen heightfield --out-dir DIR [--high-cells N] [--low-cells N] [--amplitude A] [--size S]
//   nmbake-gen sphere      --out-dir DIR [--high-cells N] [--low-cells N] [--amplitude A] [--radius R]
//   nmbake-gen torus|craters|box|slot --out-dir DIR [--high-cells N] [--low-cells N]
//   nmbake-gen box_r0.05|box_r0.1|box_r0.4|bowl|cylinder|panel --out-dir DIR   (hard_scenes.hpp)
//   nmbake-gen appearance --low L --high H --map M [--map M2 ...] [--space S] [--green G]
//              [--size N] [--supersample K] [--depth-tolerance F] [--json out.json]
//   nmbake-gen parts --out-dir DIR [--count N] [--high-triangles T]   (named parts, high as OBJ)
//   nmbake-gen eval SCENE --map M --low L [--cage C] [--samples N] [--space tangent|object]
//              [--cage-mode banded|averaged|interpolated] [--edge-band F]
//              [--front F --back B | --report bake_report.json]
//              [--retry-truth] [--json out.json] [--floors]
//   nmbake-gen convert IN OUT     (mesh formats, for the loading benchmarks)
//   nmbake-gen load FILE [--low]  (load only, for /usr/bin/time)
//   nmbake-gen maplab [--out DIR] [--size N]   (the map set against its closed forms: map_lab.hpp)
// Every scene but the moon also gets <scene>_cage.obj: the low mesh pushed
// out along averaged normals by the lab's front distance (lab_scenes.hpp).
//
// Exit codes as in DESIGN.md: 0 success, 2 bad usage or a file that cannot be
// written, 3 internal error.
#include <tbb/global_control.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "convert.hpp"
#include "eval.hpp"
#include "hard_scenes.hpp"
#include "lab_scenes.hpp"
#include "map_lab_run.hpp"
#include "nmbake/appearance.hpp"
#include "nmbake/image.hpp"
#include "nmbake/job.hpp"
#include "nmbake/load.hpp"
#include "nmbake/preview.hpp"
#include "scenes.hpp"
#include "score.hpp"

namespace {

namespace scenes = nmbake::scenes;

struct Options {
  std::string out_dir;
  int threads = 0;  // 0 = all cores
  scenes::MoonParams moon;
  scenes::HeightfieldParams heightfield;
  scenes::SphereParams sphere;
  scenes::TorusParams torus;
  scenes::CraterParams craters;
  scenes::BoxParams box;
  scenes::SlotParams slot;
  scenes::PartsParams parts;
};

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

int exit_code_of(const nmbake::Status& status) {
  return status.code() == nmbake::StatusCode::internal ? 3 : 2;
}

// Writes one mesh and prints its line; returns the exit code.
int write_mesh(const std::string& out_dir, const std::string& name, const nmbake::Mesh& mesh,
               double generate_seconds) {
  const std::string path = (std::filesystem::path(out_dir) / name).string();
  const auto start = std::chrono::steady_clock::now();
  const nmbake::Status status = nmbake::save_mesh(path, mesh);
  if (!status) {
    std::fprintf(stderr, "nmbake-gen: cannot write %s: %s\n", path.c_str(), status.message().c_str());
    return exit_code_of(status);
  }
  std::printf("wrote %s: %zu triangles, %zu vertices, write %.2f s (scene generated in %.2f s)\n",
              path.c_str(), mesh.triangle_count(), mesh.vertex_count(), seconds_since(start),
              generate_seconds);
  std::fflush(stdout);
  return 0;
}

// `high_extension` ".obj" keeps the high mesh's part names (PLY has none).
template <typename Generate>
int generate_and_write(const Options& options, const std::string& scene, const Generate& generate,
                       const char* high_extension = ".ply") {
  std::error_code error;
  std::filesystem::create_directories(options.out_dir, error);
  if (error) {
    std::fprintf(stderr, "nmbake-gen: cannot create %s: %s\n", options.out_dir.c_str(),
                 error.message().c_str());
    return 2;
  }
  const auto start = std::chrono::steady_clock::now();
  const scenes::ScenePair pair = generate();
  const double generate_seconds = seconds_since(start);
  if (const int code = write_mesh(options.out_dir, scene + "_low.obj", pair.low, generate_seconds))
    return code;
  const scenes::LabDistances distances = scenes::lab_distances(scene);
  if (distances.front > 0.0f) {
    const nmbake::Mesh cage = scenes::make_offset_cage(pair.low, distances.front);
    if (const int code = write_mesh(options.out_dir, scene + "_cage.obj", cage, generate_seconds))
      return code;
  }
  return write_mesh(options.out_dir, scene + "_high" + high_extension, pair.high, generate_seconds);
}

void add_common_options(CLI::App& command, Options& options, int& high_cells, int& low_cells) {
  command
      .add_option("--out-dir", options.out_dir, "Folder to write <scene>_low.obj and <scene>_high.ply into")
      ->required();
  command
      .add_option("--high-cells", high_cells, "Quads per side (per cube face for spheres) of the high mesh")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  command.add_option("--low-cells", low_cells, "Quads per side (per cube face for spheres) of the low mesh")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  command.add_option("--threads", options.threads, "Worker threads, 0 = all cores")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str();
}

int fail_with(const std::string& message) {
  std::fprintf(stderr, "nmbake-gen: %s\n", message.c_str());
  return 2;
}

int run_eval(const std::string& scene, const std::string& map_path, const std::string& low_path,
             const std::string& cage_path, const std::string& report_path, const std::string& json_path,
             const std::string& space, const std::string& green, const std::string& cage_mode, int samples,
             int size, float front, float back, float edge_band, bool floors, const std::string& cache,
             bool retry_truth, const std::string& truth_map) {
  scenes::EvalOptions o;
  o.samples = samples;
  if (!nmbake::is_supported_sample_count(samples)) return fail_with("--truth-samples: use 1, 4, 16 or 64");
  if (space != "tangent" && space != "object") return fail_with("--space: expected tangent or object");
  o.space = space == "object" ? nmbake::NormalSpace::object : nmbake::NormalSpace::tangent;
  o.green = green == "down" ? nmbake::GreenChannel::down : nmbake::GreenChannel::up;
  if (!nmbake::parse_word(cage_mode, o.rays.cage))
    return fail_with("--cage-mode: expected banded, averaged or interpolated");
  o.rays.edge_band = edge_band;
  if (!report_path.empty()) {
    std::ifstream in(report_path);
    if (!in) return fail_with(report_path + ": cannot read the bake report");
    try {
      const nlohmann::json j = nlohmann::json::parse(in);
      front = j.at("distances").at("front").get<float>();
      back = j.at("distances").at("back").get<float>();
      // Reports before the retry existed have none.
      if (j.at("rays").contains("retry_reach"))
        o.rays.retry_reach = j.at("rays").at("retry_reach").get<float>();
    } catch (const std::exception& e) {
      return fail_with(report_path + ": not a bake report (" + e.what() + ")");
    }
  }
  if (!(front >= 0.0f) || !(back >= 0.0f))
    return fail_with("eval needs the bake's distances: --front F --back B or --report");
  if (retry_truth) o.rays.retry_reach = -1.0f;  // resolved once the low mesh is loaded
  o.rays.front = front;
  o.rays.back = back;

  nmbake::Mesh low, cage;
  nmbake::LoadStats load_stats;
  if (const nmbake::Status st = nmbake::load_mesh(low_path, nmbake::LoadOptions{true, true}, low, load_stats);
      !st)
    return fail_with(st.message());
  nmbake::MeshStats mesh_stats;
  nmbake::prepare_low_normals(low, mesh_stats);
  if (!cage_path.empty()) {
    if (const nmbake::Status st =
            nmbake::load_mesh(cage_path, nmbake::LoadOptions{false, false}, cage, load_stats);
        !st)
      return fail_with(st.message());
    if (const nmbake::Status st = nmbake::check_cage_topology(low, cage, cage_path); !st)
      return fail_with(st.message());
  }
  nmbake::Image map;
  if (!map_path.empty()) {
    if (const nmbake::Status st = nmbake::read_image(map_path, map); !st) return fail_with(st.message());
    size = map.width;
  } else if (!floors) {
    return fail_with("eval needs --map (or --floors)");
  }
  const int width = map_path.empty() ? size : map.width, height = map_path.empty() ? size : map.height;
  if (o.rays.retry_reach < 0.0f)
    o.rays.retry_reach = nmbake::kProbeReach * nmbake::compute_bounds(low).diagonal();
  // On a low mesh without hard edges the banded cage's rays are the
  // averaged cage's: one truth serves both.
  nmbake::SurfaceStats surface_stats;
  const bool banded_differs = !nmbake::build_low_surface(low, nullptr, surface_stats).hard_corners.empty();
  const std::string ray_rule = cage_mode == "banded" && !banded_differs ? std::string("averaged") : cage_mode;
  const std::unique_ptr<scenes::TrueSurface> truth = scenes::make_true_surface(scene);
  scenes::Expected expected;
  auto stamp = [](const std::string& path) {
    std::error_code ec;
    if (path.empty()) return std::string("-");
    return path + ":" + std::to_string(std::filesystem::file_size(path, ec)) + ":" +
           std::to_string(std::filesystem::last_write_time(path, ec).time_since_epoch().count());
  };
  const std::string key =
      scene + " " + std::to_string(width) + "x" + std::to_string(height) + " s" + std::to_string(samples) +
      " " + space + " " + green + " " + ray_rule + " " +
      (cage_mode == "banded" && banded_differs ? std::to_string(edge_band) + " " : std::string()) +
      (o.rays.retry_reach > 0.0f ? "retry " + std::to_string(o.rays.retry_reach) + " " : std::string()) +
      std::to_string(front) + " " + std::to_string(back) + " " + stamp(low_path) + " " + stamp(cage_path);
  if (cache.empty() || !scenes::load_expected(cache, key, expected)) {
    expected = scenes::compute_expected(*truth, low, cage_path.empty() ? nullptr : &cage, width, height, o);
    if (!cache.empty() && !scenes::save_expected(cache, key, expected))
      return fail_with(cache + ": cannot write");
  }
  if (!truth_map.empty()) {
    // The perfect map as the evaluator sees it (float), for analyses of
    // texel errors outside this tool.
    if (const nmbake::Status st = nmbake::write_image(scenes::expected_image(expected, o), truth_map,
                                                      nmbake::PixelFormat::exr_float);
        !st) {
      return fail_with(st.message());
    }
  }
  nlohmann::ordered_json out;
  if (!map_path.empty()) {
    const scenes::EvalResult r = scenes::evaluate(expected, map, o);
    std::printf("%s %s:\n%s\n", scene.c_str(), map_path.c_str(), r.to_text().c_str());
    out["map"] = nlohmann::json::parse(r.to_json());
  }
  if (floors) {
    const nmbake::Image perfect = scenes::expected_image(expected, o);
    const std::pair<const char*, int> levels[] = {{"float", 0}, {"16bit", 65535}, {"8bit", 255}};
    for (const auto& [name, n] : levels) {
      const scenes::EvalResult r =
          scenes::evaluate(expected, n == 0 ? perfect : scenes::quantize(perfect, n), o);
      std::printf("floor %-6s %s\n", name, r.error.to_text().c_str());
      out["floors"][name] = nlohmann::json::parse(r.to_json());
    }
  }
  if (!json_path.empty()) {
    std::ofstream f(json_path);
    f << out.dump(2) << "\n";
    if (!f) return fail_with(json_path + ": cannot write");
  }
  return 0;
}

struct AppearanceFlags {
  std::string low, high, json, heat, space = "tangent", green = "up";
  float heat_max = 10.0f;
  std::vector<std::string> maps;
  nmbake::AppearanceOptions options;
};

// nmbake-gen appearance: the appearance error of one or more maps of one
// low/high pair (appearance.hpp), with the two references; the renders are
// made once and every map is scored against them.
int run_appearance(const AppearanceFlags& f) {
  if (f.space != "tangent" && f.space != "object") return fail_with("--space: expected tangent or object");
  if (f.green != "up" && f.green != "down") return fail_with("--green: expected up or down");
  const nmbake::NormalSpace space =
      f.space == "object" ? nmbake::NormalSpace::object : nmbake::NormalSpace::tangent;
  const nmbake::GreenChannel green =
      f.green == "down" ? nmbake::GreenChannel::down : nmbake::GreenChannel::up;
  nmbake::Mesh low, high;
  nmbake::LowSurface surface;
  if (const nmbake::Status st = nmbake::load_preview_meshes(f.low, f.high, low, surface, high); !st)
    return fail_with(st.message());
  std::vector<nmbake::Image> maps(f.maps.size());
  for (std::size_t i = 0; i < f.maps.size(); ++i) {
    if (const nmbake::Status st = nmbake::read_image(f.maps[i], maps[i]); !st) return fail_with(st.message());
    if (maps[i].channels < 3) return fail_with(f.maps[i] + ": a normal map needs three channels");
    if (maps[i].width != maps[0].width || maps[i].height != maps[0].height)
      return fail_with(f.maps[i] + ": every map must have the first map's size");
  }
  nmbake::AppearanceSamples samples;
  const auto start = std::chrono::steady_clock::now();
  if (const nmbake::Status st =
          nmbake::render_appearance(surface, high, maps[0].width, maps[0].height, f.options, samples);
      !st)
    return fail_with(st.message());
  const double render_seconds = seconds_since(start);
  const nmbake::AppearanceError floor = nmbake::appearance_floor(samples);
  const nmbake::AppearanceError bare = nmbake::appearance_without_map(samples, surface);
  const double compared_share =
      samples.low_hits ? static_cast<double>(samples.sample_count()) / static_cast<double>(samples.low_hits)
                       : 0.0;
  std::printf(
      "appearance: %zu views, %zu samples compared (%.1f%% of the low mesh's; high missed %llu, depth "
      "apart > %.4g %llu), rendered in %.2f s\n",
      nmbake::appearance_views().size(), samples.sample_count(), 100.0 * compared_share,
      static_cast<unsigned long long>(samples.high_missed), samples.depth_tolerance,
      static_cast<unsigned long long>(samples.depth_rejected), render_seconds);
  std::printf("%-28s %s\n", "floor (consensus)", floor.to_text().c_str());
  std::printf("%-28s %s  (%.2fx floor)\n", "low mesh, no map", bare.to_text().c_str(),
              floor.mean > 0 ? bare.mean / floor.mean : 0.0);
  nlohmann::ordered_json out;
  const auto figures = [](const nmbake::AppearanceError& e, double floor_mean) {
    nlohmann::ordered_json j;
    j["samples"] = e.samples;
    j["mean_deg"] = e.mean;
    j["p95_deg"] = e.p95;
    j["p99_deg"] = e.p99;
    j["max_deg"] = e.max;
    j["ratio_to_floor"] = floor_mean > 0.0 ? e.mean / floor_mean : 0.0;
    return j;
  };
  out["views"] = nmbake::appearance_views().size();
  out["low_samples"] = samples.low_hits;
  out["compared_samples"] = samples.sample_count();
  out["high_missed"] = samples.high_missed;
  out["depth_rejected"] = samples.depth_rejected;
  out["depth_tolerance"] = samples.depth_tolerance;
  out["floor"] = figures(floor, floor.mean);
  out["no_map"] = figures(bare, floor.mean);
  out["maps"] = nlohmann::json::array();
  std::vector<std::vector<float>> angles(maps.size() + 1);
  angles[0] = nmbake::appearance_floor_angles(samples);
  for (std::size_t i = 0; i < maps.size(); ++i) {
    std::uint64_t fallbacks = 0;
    angles[i + 1] = nmbake::appearance_angles(samples, surface, maps[i], space, green, &fallbacks);
    nmbake::AppearanceError e = nmbake::summarize_appearance(angles[i + 1]);
    e.decode_fallbacks = fallbacks;
    std::printf("%-28s %s  (%.2fx floor)\n", f.maps[i].c_str(), e.to_text().c_str(),
                floor.mean > 0 ? e.mean / floor.mean : 0.0);
    nlohmann::ordered_json j = figures(e, floor.mean);
    j["path"] = f.maps[i];
    j["decode_fallbacks"] = e.decode_fallbacks;
    out["maps"].push_back(j);
  }
  if (!f.heat.empty()) {
    std::vector<const std::vector<float>*> columns;
    for (const std::vector<float>& a : angles) columns.push_back(&a);
    const nmbake::Image heat = nmbake::appearance_heat(samples, columns, f.heat_max);
    if (const nmbake::Status st = nmbake::write_image(heat, f.heat, nmbake::PixelFormat::png8); !st)
      return fail_with(st.message());
  }
  if (!f.json.empty()) {
    std::ofstream file(f.json);
    file << out.dump(2) << "\n";
    if (!file) return fail_with(f.json + ": cannot write");
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  CLI::App app{"nmbake-gen: writes the demo moon and the analytic test scenes as low .obj + high .ply"};
  app.require_subcommand(1);

  CLI::App* moon = app.add_subcommand("moon", "Cratered moon (cube sphere; high normals area-weighted)");
  add_common_options(*moon, options, options.moon.high_cells, options.moon.low_cells);
  moon->add_option("--craters", options.moon.crater_count, "Number of craters")
      ->check(CLI::Range(0, 100000))
      ->capture_default_str();
  moon->add_option("--seed", options.moon.seed, "Seed of crater placement and noise")->capture_default_str();
  moon->add_option("--radius", options.moon.radius, "Radius of the low sphere")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();

  CLI::App* heightfield =
      app.add_subcommand("heightfield", "Smooth heightfield over [0, size]^2, analytic normals");
  add_common_options(*heightfield, options, options.heightfield.high_cells, options.heightfield.low_cells);
  heightfield->add_option("--amplitude", options.heightfield.amplitude, "Height of the bumps, scene units")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  heightfield->add_option("--size", options.heightfield.size, "Side of the square, scene units")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();

  CLI::App* sphere = app.add_subcommand("sphere", "Smoothly displaced cube sphere, analytic normals");
  add_common_options(*sphere, options, options.sphere.high_cells, options.sphere.low_cells);
  // |f| stays below ~1.3, so up to 0.3 the radius stays well above zero.
  sphere->add_option("--amplitude", options.sphere.amplitude, "Relative displacement amplitude")
      ->check(CLI::Range(0.0f, 0.3f))
      ->capture_default_str();
  sphere->add_option("--radius", options.sphere.radius, "Radius of the low sphere")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();

  CLI::App* torus = app.add_subcommand("torus", "Torus with smooth bumps on the tube, analytic normals");
  add_common_options(*torus, options, options.torus.high_cells, options.torus.low_cells);
  CLI::App* craters =
      app.add_subcommand("craters", "Cube-sphere moon with C1-smooth craters, analytic normals");
  add_common_options(*craters, options, options.craters.high_cells, options.craters.low_cells);
  CLI::App* box = app.add_subcommand("box", "Hard-edged low cube over a bevelled (rounded) high cube");
  add_common_options(*box, options, options.box.high_cells, options.box.low_cells);
  CLI::App* slot = app.add_subcommand("slot", "Concave U groove with bumps: long rays cross the far wall");
  add_common_options(*slot, options, options.slot.high_cells, options.slot.low_cells);

  // The hard-edged and concave scenes (hard_scenes.hpp), fixed parameters.
  std::vector<std::pair<std::string, CLI::App*>> hard;
  for (const std::string& name : scenes::hard_scene_names()) {
    CLI::App* cmd = app.add_subcommand(
        name, name == "bowl"       ? "Dish turned around y: concave and convex hard edges, filleted high"
              : name == "cylinder" ? "Cylinder, hard-edged caps in the low mesh, chamfered in the high"
              : name == "panel" ? "Hard-edged slab with pockets, a groove and a deep dimple carved in its top"
                                : "Hard-edged low cube over a rounded high cube of this bevel radius");
    cmd->add_option("--out-dir", options.out_dir, "Folder to write <scene>_low.obj and <scene>_high.ply into")
        ->required();
    cmd->add_option("--threads", options.threads, "Worker threads, 0 = all cores")
        ->check(CLI::Range(0, 1024));
    hard.emplace_back(name, cmd);
  }

  CLI::App* parts = app.add_subcommand(
      "parts", "Many heightfield plates, each a named part (p<i>_low / p<i>_high, high as OBJ)");
  parts->add_option("--out-dir", options.out_dir, "Folder to write parts_low.obj and parts_high.obj into")
      ->required();
  parts->add_option("--count", options.parts.count, "Number of parts")
      ->check(CLI::Range(1, 10000))
      ->capture_default_str();
  parts->add_option("--high-triangles", options.parts.high_triangles, "High triangles in all (about)")
      ->capture_default_str();
  parts->add_option("--threads", options.threads, "Worker threads, 0 = all cores")
      ->check(CLI::Range(0, 1024));

  // The lab's evaluator (eval.hpp).
  struct EvalFlags {
    std::string scene, map, low, cage, report, json, space = "tangent", cage_mode = "banded", green = "up";
    float edge_band = nmbake::kDefaultEdgeBand;
    int samples = 64, size = 512;
    std::string cache;
    std::string truth_map;
    float front = -1.0f, back = -1.0f;
    bool floors = false, retry_truth = false;
  } ev;
  CLI::App* eval_cmd =
      app.add_subcommand("eval", "Coverage and angular error of a baked map of an analytic scene");
  eval_cmd->add_option("scene", ev.scene, "heightfield | sphere | torus | craters | box | slot")
      ->required()
      ->check(CLI::IsMember(scenes::lab_scene_names()));
  eval_cmd->add_option("--map", ev.map, "the baked map (EXR for the exact value)");
  eval_cmd->add_option("--low", ev.low, "the low mesh that was baked")->required();
  eval_cmd->add_option("--cage", ev.cage, "the explicit cage the bake used, if any");
  eval_cmd
      ->add_option("--truth-samples", ev.samples, "samples per texel of the truth (box filter): 1, 4, 16, 64")
      ->capture_default_str();
  eval_cmd->add_option("--cache", ev.cache,
                       "keep the computed truth in this file and reuse it when it matches");
  eval_cmd->add_option("--truth-map", ev.truth_map, "also write the perfect map (the truth, float EXR) here");
  eval_cmd->add_option("--space", ev.space, "tangent | object")->capture_default_str();
  eval_cmd->add_option("--green", ev.green, "up | down")->capture_default_str();
  eval_cmd->add_option("--cage-mode", ev.cage_mode, "banded | averaged | interpolated (the bake's)")
      ->capture_default_str();
  eval_cmd->add_option("--edge-band", ev.edge_band, "the bake's --edge-band (banded cage)")
      ->capture_default_str();
  eval_cmd->add_option("--front", ev.front, "the bake's front distance, scene units");
  eval_cmd->add_option("--back", ev.back, "the bake's back distance, scene units");
  eval_cmd->add_option("--report", ev.report, "read the resolved front/back from this bake report");
  eval_cmd->add_option("--json", ev.json, "also write the figures here");
  eval_cmd->add_option("--size", ev.size, "--floors without --map: map size")->capture_default_str();
  eval_cmd->add_option("--threads", options.threads, "Worker threads, 0 = all cores")
      ->check(CLI::Range(0, 1024));
  eval_cmd->add_flag(
      "--retry-truth", ev.retry_truth,
      "where the bake's ray meets no true surface, search its line out and in up to the distance probes' "
      "reach (as a retried bake does), whatever the bake did: a miss then counts as an error");
  eval_cmd->add_flag("--floors", ev.floors,
                     "score the perfect map as float, 16-bit and 8-bit (the evaluator's floors)");

  AppearanceFlags ap;
  CLI::App* appearance_cmd = app.add_subcommand(
      "appearance", "What a renderer shows: high normals vs the low mesh with each map, from 14 cameras");
  appearance_cmd->add_option("--low", ap.low, "the low mesh that was baked")->required();
  appearance_cmd->add_option("--high", ap.high, "the high mesh")->required();
  appearance_cmd->add_option("--map", ap.maps, "a baked map (repeat: every map is scored against one render)")
      ->required();
  appearance_cmd->add_option("--space", ap.space, "tangent | object")->capture_default_str();
  appearance_cmd->add_option("--green", ap.green, "up | down")->capture_default_str();
  appearance_cmd->add_option("--size", ap.options.size, "pixels per side of each view")
      ->capture_default_str();
  appearance_cmd->add_option("--supersample", ap.options.supersample, "k x k samples per pixel")
      ->capture_default_str();
  appearance_cmd
      ->add_option("--depth-tolerance", ap.options.depth_tolerance,
                   "compare samples whose low and high hits are at most this share of the diagonal apart")
      ->capture_default_str();
  appearance_cmd->add_option("--json", ap.json, "also write the figures here");
  appearance_cmd->add_option("--heat", ap.heat,
                             "write where the error is (PNG): a row per view, the floor then each map");
  appearance_cmd->add_option("--heat-max", ap.heat_max, "degrees at the red end of the heat ramp")
      ->capture_default_str();
  appearance_cmd->add_option("--threads", options.threads, "Worker threads, 0 = all cores")
      ->check(CLI::Range(0, 1024));

  // Scoring a bake of an analytic scene against its true normals.
  struct ScoreOptions {
    std::string scene, map, low;
    int samples = 4;
    float front = 0.0f, back = 0.0f;
  } score;
  CLI::App* score_cmd =
      app.add_subcommand("score", "Angular error of a baked map of the heightfield or sphere scene");
  score_cmd->add_option("scene", score.scene, "heightfield | sphere")
      ->required()
      ->check(CLI::IsMember({"heightfield", "sphere"}));
  score_cmd->add_option("--map", score.map, "the baked tangent-space map (EXR for the exact value)")
      ->required();
  score_cmd->add_option("--samples", score.samples, "samples per texel of the bake")->capture_default_str();
  score_cmd->add_option("--low", score.low, "sphere: the low mesh that was baked");
  score_cmd->add_option("--front", score.front, "sphere: the bake's front distance (from its report)");
  score_cmd->add_option("--back", score.back, "sphere: the bake's back distance (from its report)");
  score_cmd->add_option("--amplitude", options.sphere.amplitude, "the scene's amplitude (sphere: relative)");
  score_cmd->add_option("--size", options.heightfield.size, "heightfield: side of the square");
  score_cmd->add_option("--radius", options.sphere.radius, "sphere: radius");

  std::string convert_in, convert_out, load_file;
  bool load_low = false;
  CLI::App* convert_cmd =
      app.add_subcommand("convert", "Convert a mesh: .obj .ply .glb .gltf(+.bin) .fbx (Assimp)");
  convert_cmd->add_option("in", convert_in, "input mesh")->required();
  convert_cmd->add_option("out", convert_out, "output mesh, format by extension")->required();
  CLI::App* maplab =
      app.add_subcommand("maplab", "Bake every map of the map set on its analytic scenes, score it");
  std::string maplab_out = "out/lab";
  int maplab_size = 128;
  maplab->add_option("--out", maplab_out, "folder for maps_lab.csv, maps_lab.md and the bakes")
      ->capture_default_str();
  maplab->add_option("--size", maplab_size, "map size")->capture_default_str()->check(CLI::Range(16, 4096));
  CLI::App* load_cmd = app.add_subcommand("load", "Load a mesh and print its counts and load time");
  load_cmd->add_option("file", load_file, "mesh file")->required();
  load_cmd->add_flag("--low", load_low, "load as a low mesh (with UVs)");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }

  try {
    std::unique_ptr<tbb::global_control> thread_limit;
    if (options.threads > 0) {
      thread_limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                           static_cast<std::size_t>(options.threads));
    }
    if (convert_cmd->parsed() || load_cmd->parsed()) {
      const nmbake::Status st = convert_cmd->parsed() ? nmbake::gen::convert_mesh(convert_in, convert_out)
                                                      : nmbake::gen::load_only(load_file, load_low);
      if (!st) {
        std::fprintf(stderr, "nmbake-gen: %s\n", st.message().c_str());
        return st.code() == nmbake::StatusCode::internal ? 3 : 2;
      }
      return 0;
    }
    if (score_cmd->parsed()) {
      nmbake::Image map;
      if (const nmbake::Status st = nmbake::read_image(score.map, map); !st) {
        std::fprintf(stderr, "nmbake-gen: %s\n", st.message().c_str());
        return 2;
      }
      scenes::AngularError e;
      if (score.scene == "heightfield") {
        if (score_cmd->count("--amplitude")) options.heightfield.amplitude = options.sphere.amplitude;
        e = scenes::score_heightfield(options.heightfield, map, score.samples);
      } else {
        nmbake::Mesh low;
        nmbake::LoadStats load_stats;
        if (const nmbake::Status st = nmbake::load_mesh(score.low, {}, low, load_stats); !st) {
          std::fprintf(stderr, "nmbake-gen: %s\n", st.message().c_str());
          return 2;
        }
        nmbake::MeshStats mesh_stats;
        nmbake::prepare_low_normals(low, mesh_stats);
        e = scenes::score_sphere(options.sphere, low, map, score.samples, score.front, score.back);
      }
      std::printf("%s %s: %s\n", score.scene.c_str(), score.map.c_str(), e.to_text().c_str());
      return 0;
    }
    if (maplab->parsed()) return scenes::run_map_lab(maplab_out, maplab_size);
    if (appearance_cmd->parsed()) return run_appearance(ap);
    if (eval_cmd->parsed())
      return run_eval(ev.scene, ev.map, ev.low, ev.cage, ev.report, ev.json, ev.space, ev.green, ev.cage_mode,
                      ev.samples, ev.size, ev.front, ev.back, ev.edge_band, ev.floors, ev.cache,
                      ev.retry_truth, ev.truth_map);
    for (const auto& [name, cmd] : hard) {
      if (!cmd->parsed()) continue;
      return generate_and_write(options, name, [&name = name] {
        scenes::ScenePair pair;
        NMBAKE_CHECK(scenes::make_hard_scene(name, pair), "a hard scene name");
        return pair;
      });
    }
    if (torus->parsed())
      return generate_and_write(options, "torus", [&] { return scenes::make_torus(options.torus); });
    if (craters->parsed()) {
      return generate_and_write(options, "craters", [&] { return scenes::make_craters(options.craters); });
    }
    if (parts->parsed()) {
      return generate_and_write(
          options, "parts", [&] { return scenes::make_parts(options.parts); }, ".obj");
    }
    if (box->parsed())
      return generate_and_write(options, "box", [&] { return scenes::make_box(options.box); });
    if (slot->parsed())
      return generate_and_write(options, "slot", [&] { return scenes::make_slot(options.slot); });
    if (moon->parsed()) {
      return generate_and_write(options, "moon", [&] { return scenes::make_moon(options.moon); });
    }
    if (heightfield->parsed()) {
      if (options.heightfield.amplitude > options.heightfield.size) {
        std::fprintf(stderr, "nmbake-gen: --amplitude must not exceed --size\n");
        return 2;
      }
      return generate_and_write(options, "heightfield",
                                [&] { return scenes::make_heightfield(options.heightfield); });
    }
    return generate_and_write(options, "sphere",
                              [&] { return scenes::make_displaced_sphere(options.sphere); });
  } catch (const std::exception& e) {
    std::fprintf(stderr, "nmbake-gen: internal error: %s\n", e.what());
    return 3;
  }
}
