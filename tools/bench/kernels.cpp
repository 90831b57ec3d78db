// Google Benchmark kernels of the stages that are not ray casting: each must
// stay small beside trace (issue: no stage other than load, BVH build and
// trace above 10% of a bake). Scenes come from the generators.
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <glm/geometric.hpp>
#include <string>

#include "nmbake/bake.hpp"
#include "nmbake/maps.hpp"
#include "scenes.hpp"

namespace {

using namespace nmbake;

const scenes::ScenePair& moon() {
  static const scenes::ScenePair pair = [] {
    scenes::MoonParams p;
    p.high_cells = 289;  // ~1M triangles
    return scenes::make_moon(p);
  }();
  return pair;
}

const LowSurface& moon_surface() {
  static const LowSurface surface = [] {
    Mesh low = moon().low;
    SurfaceStats stats;
    return build_low_surface(low, nullptr, stats);
  }();
  return surface;
}

std::string temp_file(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          ("nmbake_kernels_" + std::to_string(::getpid()) + "_" + name))
      .string();
}

void BM_Raster(benchmark::State& state) {
  const int size = static_cast<int>(state.range(0));
  const int spp = static_cast<int>(state.range(1));
  TexelSamples samples;
  for (auto _ : state) {
    RasterStats stats;
    rasterize(moon_surface(), size, size, spp, samples, stats);
    benchmark::DoNotOptimize(samples.triangle.data());
  }
  state.SetItemsProcessed(state.iterations() * size * size * spp);
}
BENCHMARK(BM_Raster)->Args({2048, 1})->Args({2048, 4})->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_Tangents(benchmark::State& state) {
  scenes::SphereParams p;
  p.low_cells = static_cast<int>(state.range(0));
  const Mesh low = scenes::make_displaced_sphere(p).low;
  std::vector<glm::vec4> tangents;
  for (auto _ : state) {
    TangentStats stats;
    compute_tangents(low, tangents, stats);
    benchmark::DoNotOptimize(tangents.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(low.triangle_count()));
}
BENCHMARK(BM_Tangents)->Arg(16)->Arg(128)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_Dilate(benchmark::State& state) {
  const int size = static_cast<int>(state.range(0));
  TexelSamples samples;
  RasterStats rs;
  rasterize(moon_surface(), size, size, 1, samples, rs);
  Image image{size, size, 3, std::vector<float>(static_cast<std::size_t>(size) * size * 3, 0.5f)};
  for (auto _ : state) {
    std::vector<std::uint8_t> coverage = samples.coverage;
    DilateStats stats;
    dilate(image, coverage, 16, stats);
    benchmark::DoNotOptimize(image.pixels.data());
  }
}
BENCHMARK(BM_Dilate)->Arg(2048)->Arg(4096)->Unit(benchmark::kMillisecond)->UseRealTime();

// The map set's layers (normal, height, position, curvature) in one
// dilation, as a bake of those maps runs it.
void BM_DilateSet(benchmark::State& state) {
  const int size = static_cast<int>(state.range(0));
  TexelSamples samples;
  RasterStats rs;
  rasterize(moon_surface(), size, size, 1, samples, rs);
  const std::size_t texels = static_cast<std::size_t>(size) * size;
  Image normal{size, size, 3, std::vector<float>(texels * 3, 0.5f)};
  Image height{size, size, 1, std::vector<float>(texels, 0.25f)};
  Image position{size, size, 3, std::vector<float>(texels * 3, 0.75f)};
  Image curvature{size, size, 1, std::vector<float>(texels, 0.5f)};
  const std::vector<DilateLayer> layers = {{&normal, DilateMode::unit_vector},
                                           {&height, DilateMode::mean},
                                           {&position, DilateMode::mean},
                                           {&curvature, DilateMode::mean}};
  std::vector<std::uint8_t> coverage(samples.coverage.size());
  for (auto _ : state) {
    std::copy(samples.coverage.begin(), samples.coverage.end(), coverage.begin());
    DilateStats stats;
    dilate(layers, coverage, 16, stats);
    benchmark::DoNotOptimize(curvature.pixels.data());
  }
}
BENCHMARK(BM_DilateSet)->Name("BM_Dilate/set")->Arg(2048)->Unit(benchmark::kMillisecond)->UseRealTime();

// Vertex mean curvature of the moon's ~1M-triangle high mesh (the
// curvature map's pass over the high mesh, in the prepare stage).
void BM_Curvature(benchmark::State& state) {
  static const Mesh high = [] {
    Mesh m = moon().high;
    MeshStats stats;
    if (!m.has_normals()) compute_vertex_normals(m, stats);
    return m;
  }();
  for (auto _ : state) {
    CurvatureStats stats;
    std::vector<float> curvature = vertex_mean_curvature(high, high.normals, stats);
    benchmark::DoNotOptimize(curvature.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(high.triangle_count()));
}
BENCHMARK(BM_Curvature)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_Load(benchmark::State& state, const char* extension) {
  const std::string path = temp_file(std::string("high") + extension);
  if (!save_mesh(path, moon().high)) {
    state.SkipWithError("cannot write the mesh");
    return;
  }
  const auto bytes = static_cast<std::int64_t>(std::filesystem::file_size(path));
  for (auto _ : state) {
    Mesh mesh;
    LoadStats stats;
    if (!load_mesh(path, LoadOptions{false, true}, mesh, stats)) state.SkipWithError("load failed");
    benchmark::DoNotOptimize(mesh.positions.data());
  }
  state.SetBytesProcessed(state.iterations() * bytes);
  std::filesystem::remove(path);
}
BENCHMARK_CAPTURE(BM_Load, ply, ".ply")->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Load, obj, ".obj")->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_Write(benchmark::State& state, PixelFormat format, const char* extension) {
  const int size = 2048;
  // A tangent-space map like a bake's: the normals of a bumpy height field,
  // plus the detail a sculpt leaves below the 16-bit step (a hash, +-1e-4):
  // without it the low bytes repeat with the waves' period, which no real
  // map does, and string matching looks far better than on real bakes.
  Image image{size, size, 3, std::vector<float>(static_cast<std::size_t>(size) * size * 3)};
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      const float u = 6.2831853f * static_cast<float>(x) / 97.0f,
                  v = 6.2831853f * static_cast<float>(y) / 131.0f;
      const glm::vec3 n = glm::normalize(
          glm::vec3(-0.3f * std::cos(u) * std::sin(0.7f * v),
                    -0.2f * std::sin(u) * std::cos(0.7f * v) - 0.1f * std::cos(3.1f * v), 1.0f));
      float* p = &image.pixels[(static_cast<std::size_t>(y) * size + x) * 3];
      for (int c = 0; c < 3; ++c) {
        const std::uint32_t h = (static_cast<std::uint32_t>(y * size + x) * 3u + c) * 2654435761u;
        p[c] = 0.5f * n[c] + 0.5f + 1e-4f * (static_cast<float>(h >> 16) / 32768.0f - 1.0f);
      }
    }
  }
  const std::string path = temp_file(std::string("map") + extension);
  for (auto _ : state) {
    if (!write_image(image, path, format)) state.SkipWithError("write failed");
  }
  std::filesystem::remove(path);
}
BENCHMARK_CAPTURE(BM_Write, png16, PixelFormat::png16, ".png")->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Write, exr_float, PixelFormat::exr_float, ".exr")
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// A curvature map as a bake writes it: one channel, 8 bits, dithered (the
// default for 8-bit maps), values around 0.5 with smooth swells and a
// sub-step hash like BM_Write's.
void BM_WriteDithered(benchmark::State& state) {
  const int size = 2048;
  Image image{size, size, 1, std::vector<float>(static_cast<std::size_t>(size) * size)};
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      const float u = 6.2831853f * static_cast<float>(x) / 97.0f,
                  v = 6.2831853f * static_cast<float>(y) / 131.0f;
      const std::uint32_t h = static_cast<std::uint32_t>(y * size + x) * 2654435761u;
      image.pixels[static_cast<std::size_t>(y) * size + x] =
          0.5f + 0.2f * std::sin(u) * std::cos(0.7f * v) +
          1e-3f * (static_cast<float>(h >> 16) / 32768.0f - 1.0f);
    }
  }
  const std::string path = temp_file("curvature.png");
  WriteOptions options;
  options.dither = true;
  for (auto _ : state) {
    if (!write_image(image, path, PixelFormat::png8, options)) state.SkipWithError("write failed");
  }
  std::filesystem::remove(path);
}
BENCHMARK(BM_WriteDithered)->Name("BM_Write/png8_dither")->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
