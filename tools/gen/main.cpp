// nmbake-gen: writes the generated scenes (scenes.hpp) as a low .obj and a
// high .ply, for the demo, the lab and regression bakes.
//
//   nmbake-gen moon        --out-dir DIR [--high-cells N] [--low-cells N] [--craters N] [--seed S] [--radius
//   R] nmbake-gen heightfield --out-dir DIR [--high-cells N] [--low-cells N] [--amplitude A] [--size S]
//   nmbake-gen sphere      --out-dir DIR [--high-cells N] [--low-cells N] [--amplitude A] [--radius R]
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

#include "nmbake/load.hpp"
#include "nmbake/image.hpp"
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

template <typename Generate>
int generate_and_write(const Options& options, const std::string& scene, const Generate& generate) {
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
  return write_mesh(options.out_dir, scene + "_high.ply", pair.high, generate_seconds);
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
        nmbake::normalize_normals(low, mesh_stats);
        e = scenes::score_sphere(options.sphere, low, map, score.samples, score.front, score.back);
      }
      std::printf("%s %s: %s\n", score.scene.c_str(), score.map.c_str(), e.to_text().c_str());
      return 0;
    }
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
