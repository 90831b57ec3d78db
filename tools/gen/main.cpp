// nmbake-gen: writes the generated scenes (scenes.hpp) as a low .obj and a
// high .ply, for the demo, the lab and regression bakes.
//
//   nmbake-gen moon        --out-dir DIR [--high-cells N] [--low-cells N] [--craters N] [--seed S] [--radius
//   R] nmbake-gen heightfield --out-dir DIR [--high-cells N] [--low-cells N] [--amplitude A] [--size S]
//   nmbake-gen sphere      --out-dir DIR [--high-cells N] [--low-cells N] [--amplitude A] [--radius R]
//   nmbake-gen torus|craters|box|slot --out-dir DIR [--high-cells N] [--low-cells N]
//   nmbake-gen parts --out-dir DIR [--count N] [--high-triangles T]   (named parts, high as OBJ)
//   nmbake-gen eval SCENE --map M --low L [--cage C] [--samples N] [--space tangent|object]
//              [--cage-mode averaged|interpolated] [--front F --back B | --report bake_report.json]
//              [--json out.json] [--floors]
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
#include <memory>
#include <string>

#include <fstream>
#include <nlohmann/json.hpp>

#include "convert.hpp"
#include "eval.hpp"
#include "lab_scenes.hpp"
#include "map_lab_run.hpp"
#include "nmbake/image.hpp"
#include "nmbake/load.hpp"
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
    if (const int code = write_mesh(options.out_dir, scene + "_cage.obj", cage, generate_seconds)) return code;
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
             int size, float front, float back, bool floors, const std::string& cache,
             const std::string& truth_map) {
  scenes::EvalOptions o;
  o.samples = samples;
  if (!nmbake::is_supported_sample_count(samples)) return fail_with("--truth-samples: use 1, 4, 16 or 64");
  if (space != "tangent" && space != "object") return fail_with("--space: expected tangent or object");
  o.space = space == "object" ? nmbake::NormalSpace::object : nmbake::NormalSpace::tangent;
  o.green = green == "down" ? nmbake::GreenChannel::down : nmbake::GreenChannel::up;
  if (cage_mode != "averaged" && cage_mode != "interpolated") return fail_with("--cage-mode: expected averaged or interpolated");
  o.rays.cage = cage_mode == "interpolated" ? nmbake::CageMode::interpolated : nmbake::CageMode::averaged;
  if (!report_path.empty()) {
    std::ifstream in(report_path);
    if (!in) return fail_with(report_path + ": cannot read the bake report");
    try {
      const nlohmann::json j = nlohmann::json::parse(in);
      front = j.at("distances").at("front").get<float>();
      back = j.at("distances").at("back").get<float>();
    } catch (const std::exception& e) {
      return fail_with(report_path + ": not a bake report (" + e.what() + ")");
    }
  }
  if (!(front >= 0.0f) || !(back >= 0.0f)) return fail_with("eval needs the bake's distances: --front F --back B or --report");
  o.rays.front = front;
  o.rays.back = back;

  nmbake::Mesh low, cage;
  nmbake::LoadStats load_stats;
  if (const nmbake::Status st = nmbake::load_mesh(low_path, nmbake::LoadOptions{true, true}, low, load_stats); !st)
    return fail_with(st.message());
  nmbake::MeshStats mesh_stats;
  nmbake::prepare_low_normals(low, mesh_stats);
  if (!cage_path.empty()) {
    if (const nmbake::Status st = nmbake::load_mesh(cage_path, nmbake::LoadOptions{false, false}, cage, load_stats); !st)
      return fail_with(st.message());
    if (const nmbake::Status st = nmbake::check_cage_topology(low, cage, cage_path); !st) return fail_with(st.message());
  }
  nmbake::Image map;
  if (!map_path.empty()) {
    if (const nmbake::Status st = nmbake::read_image(map_path, map); !st) return fail_with(st.message());
    size = map.width;
  } else if (!floors) {
    return fail_with("eval needs --map (or --floors)");
  }
  const int width = map_path.empty() ? size : map.width, height = map_path.empty() ? size : map.height;
  const std::unique_ptr<scenes::TrueSurface> truth = scenes::make_true_surface(scene);
  scenes::Expected expected;
  auto stamp = [](const std::string& path) {
    std::error_code ec;
    if (path.empty()) return std::string("-");
    return path + ":" + std::to_string(std::filesystem::file_size(path, ec)) + ":" +
           std::to_string(std::filesystem::last_write_time(path, ec).time_since_epoch().count());
  };
  const std::string key = scene + " " + std::to_string(width) + "x" + std::to_string(height) + " s" +
                          std::to_string(samples) + " " + space + " " + green + " " + cage_mode + " " +
                          std::to_string(front) + " " + std::to_string(back) + " " + stamp(low_path) + " " +
                          stamp(cage_path);
  if (cache.empty() || !scenes::load_expected(cache, key, expected)) {
    expected = scenes::compute_expected(*truth, low, cage_path.empty() ? nullptr : &cage, width, height, o);
    if (!cache.empty() && !scenes::save_expected(cache, key, expected)) return fail_with(cache + ": cannot write");
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
      const scenes::EvalResult r = scenes::evaluate(expected, n == 0 ? perfect : scenes::quantize(perfect, n), o);
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
  CLI::App* craters = app.add_subcommand("craters", "Cube-sphere moon with C1-smooth craters, analytic normals");
  add_common_options(*craters, options, options.craters.high_cells, options.craters.low_cells);
  CLI::App* box = app.add_subcommand("box", "Hard-edged low cube over a bevelled (rounded) high cube");
  add_common_options(*box, options, options.box.high_cells, options.box.low_cells);
  CLI::App* slot = app.add_subcommand("slot", "Concave U groove with bumps: long rays cross the far wall");
  add_common_options(*slot, options, options.slot.high_cells, options.slot.low_cells);

  CLI::App* parts = app.add_subcommand("parts", "Many heightfield plates, each a named part (p<i>_low / p<i>_high, high as OBJ)");
  parts->add_option("--out-dir", options.out_dir, "Folder to write parts_low.obj and parts_high.obj into")->required();
  parts->add_option("--count", options.parts.count, "Number of parts")->check(CLI::Range(1, 10000))->capture_default_str();
  parts->add_option("--high-triangles", options.parts.high_triangles, "High triangles in all (about)")->capture_default_str();
  parts->add_option("--threads", options.threads, "Worker threads, 0 = all cores")->check(CLI::Range(0, 1024));

  // The lab's evaluator (eval.hpp).
  struct EvalFlags {
    std::string scene, map, low, cage, report, json, space = "tangent", cage_mode = "averaged", green = "up";
    int samples = 64, size = 512;
    std::string cache;
    std::string truth_map;
    float front = -1.0f, back = -1.0f;
    bool floors = false;
  } ev;
  CLI::App* eval_cmd = app.add_subcommand("eval", "Coverage and angular error of a baked map of an analytic scene");
  eval_cmd->add_option("scene", ev.scene, "heightfield | sphere | torus | craters | box | slot")
      ->required()
      ->check(CLI::IsMember(scenes::lab_scene_names()));
  eval_cmd->add_option("--map", ev.map, "the baked map (EXR for the exact value)");
  eval_cmd->add_option("--low", ev.low, "the low mesh that was baked")->required();
  eval_cmd->add_option("--cage", ev.cage, "the explicit cage the bake used, if any");
  eval_cmd->add_option("--truth-samples", ev.samples, "samples per texel of the truth (box filter): 1, 4, 16, 64")
      ->capture_default_str();
  eval_cmd->add_option("--cache", ev.cache,
                       "keep the computed truth in this file and reuse it when it matches");
  eval_cmd->add_option("--truth-map", ev.truth_map, "also write the perfect map (the truth, float EXR) here");
  eval_cmd->add_option("--space", ev.space, "tangent | object")->capture_default_str();
  eval_cmd->add_option("--green", ev.green, "up | down")->capture_default_str();
  eval_cmd->add_option("--cage-mode", ev.cage_mode, "averaged | interpolated (the bake's)")->capture_default_str();
  eval_cmd->add_option("--front", ev.front, "the bake's front distance, scene units");
  eval_cmd->add_option("--back", ev.back, "the bake's back distance, scene units");
  eval_cmd->add_option("--report", ev.report, "read the resolved front/back from this bake report");
  eval_cmd->add_option("--json", ev.json, "also write the figures here");
  eval_cmd->add_option("--size", ev.size, "--floors without --map: map size")->capture_default_str();
  eval_cmd->add_option("--threads", options.threads, "Worker threads, 0 = all cores")->check(CLI::Range(0, 1024));
  eval_cmd->add_flag("--floors", ev.floors, "score the perfect map as float, 16-bit and 8-bit (the evaluator's floors)");

  // Scoring a bake of an analytic scene against its true normals.
  struct ScoreOptions {
    std::string scene, map, low;
    int samples = 4;
    float front = 0.0f, back = 0.0f;
  } score;
  CLI::App* score_cmd = app.add_subcommand("score", "Angular error of a baked map of the heightfield or sphere scene");
  score_cmd->add_option("scene", score.scene, "heightfield | sphere")->required()->check(CLI::IsMember({"heightfield", "sphere"}));
  score_cmd->add_option("--map", score.map, "the baked tangent-space map (EXR for the exact value)")->required();
  score_cmd->add_option("--samples", score.samples, "samples per texel of the bake")->capture_default_str();
  score_cmd->add_option("--low", score.low, "sphere: the low mesh that was baked");
  score_cmd->add_option("--front", score.front, "sphere: the bake's front distance (from its report)");
  score_cmd->add_option("--back", score.back, "sphere: the bake's back distance (from its report)");
  score_cmd->add_option("--amplitude", options.sphere.amplitude, "the scene's amplitude (sphere: relative)");
  score_cmd->add_option("--size", options.heightfield.size, "heightfield: side of the square");
  score_cmd->add_option("--radius", options.sphere.radius, "sphere: radius");

  std::string convert_in, convert_out, load_file;
  bool load_low = false;
  CLI::App* convert_cmd = app.add_subcommand("convert", "Convert a mesh: .obj .ply .glb .gltf(+.bin) .fbx (Assimp)");
  convert_cmd->add_option("in", convert_in, "input mesh")->required();
  convert_cmd->add_option("out", convert_out, "output mesh, format by extension")->required();
  CLI::App* maplab = app.add_subcommand("maplab", "Bake every map of the map set on its analytic scenes, score it");
  std::string maplab_out = "out/lab";
  int maplab_size = 128;
  maplab->add_option("--out", maplab_out, "folder for maps_lab.csv, maps_lab.md and the bakes")->capture_default_str();
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
    if (eval_cmd->parsed())
      return run_eval(ev.scene, ev.map, ev.low, ev.cage, ev.report, ev.json, ev.space, ev.green, ev.cage_mode,
                      ev.samples, ev.size, ev.front, ev.back, ev.floors, ev.cache, ev.truth_map);
    if (torus->parsed())
      return generate_and_write(options, "torus", [&] { return scenes::make_torus(options.torus); });
    if (craters->parsed()) {
      return generate_and_write(options, "craters", [&] { return scenes::make_craters(options.craters); });
    }
    if (parts->parsed()) {
      return generate_and_write(options, "parts", [&] { return scenes::make_parts(options.parts); }, ".obj");
    }
    if (box->parsed()) return generate_and_write(options, "box", [&] { return scenes::make_box(options.box); });
    if (slot->parsed()) return generate_and_write(options, "slot", [&] { return scenes::make_slot(options.slot); });
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
