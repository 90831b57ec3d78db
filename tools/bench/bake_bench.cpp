// nmbake-bench: one whole bake beside the raw speed of Embree for the same
// rays, in one process, printed as one fixed-format line (tools/bench runs it
// over the benchmark scenes). Timings are medians of --repeat runs; bake and
// raw runs alternate, and the ratio is the median of each pair's ratio.
//
//   nmbake-bench --low L --high H --size 2048 --samples 4 [--threads N] [--repeat 3] [--compare-old-rule N]
//
// The bake is the library's bake() with default options (auto distances,
// averaged cage) writing a 16-bit PNG to a temp folder; "raw" is trace_raw():
// the bake's first-hit rays, prebuilt, fired as the same packets with only
// rtcIntersect16 timed.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <tbb/global_control.h>
#include <unistd.h>

#include "nmbake/bake.hpp"
#include "nmbake/job.hpp"

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

double stage(const nmbake::BakeReport& r, const char* name) {
  for (const auto& s : r.stages)
    if (s.name == name) return s.seconds;
  return 0.0;
}

}  // namespace

int main(int argc, char** argv) {
  std::string low, high, label, bvh = "auto", quality = "low";
  int size = 2048, samples = 4, threads = 0, repeat = 3;
  std::size_t band_samples = 0;
  int compare_pairs = 0;
  CLI::App app{"nmbake-bench: a whole bake beside raw Embree on the same rays"};
  app.add_option("--low", low)->required();
  app.add_option("--high", high)->required();
  app.add_option("--label", label, "scene name printed in the line");
  app.add_option("--size", size)->capture_default_str();
  app.add_option("--samples", samples)->capture_default_str();
  app.add_option("--threads", threads, "0 = all cores")->capture_default_str();
  app.add_option("--bvh", bvh, "auto | fast | compact")->capture_default_str();
  app.add_option("--build-quality", quality, "low | medium | high")->capture_default_str();
  app.add_option("--repeat", repeat)->capture_default_str()->check(CLI::Range(1, 50));
  app.add_option("--band-samples", band_samples, "samples per band of rows (0: the library's default, 1M)")
      ->capture_default_str();
  app.add_option("--compare-old-rule", compare_pairs,
                 "then N passes over the map's bands, each band traced with the defaults and with the old ray rule "
                 "(averaged cage, no retry) in turn: the median of the passes' trace-time ratios")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  if (label.empty()) label = std::filesystem::path(high).stem().string();

  std::unique_ptr<tbb::global_control> limit;
  if (threads > 0) {
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  static_cast<std::size_t>(threads));
  }
  const auto dir = std::filesystem::temp_directory_path() / ("nmbake_bench_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);

  nmbake::BakeOptions o;
  o.low_path = low;
  o.high_path = high;
  o.width = o.height = size;
  o.samples = samples;
  o.band_samples = band_samples;
  o.outputs = {{(dir / "map.png").string(), nmbake::PixelFormat::png16}};
  if (!nmbake::parse_build_quality(quality, o.build_quality)) {
    std::fprintf(stderr, "nmbake-bench: --build-quality %s: expected low, medium or high\n", quality.c_str());
    return 2;
  }
  if (!nmbake::parse_bvh_memory(bvh, o.bvh_memory)) {
    std::fprintf(stderr, "nmbake-bench: --bvh %s: expected auto, fast or compact\n", bvh.c_str());
    return 2;
  }

  // rest: prepare (normals, tangents) + distances (auto estimate) + dilate.
  std::vector<double> load, build, raster, trace, encode, write, rest, total, raw, ratio;
  nmbake::BakeReport report;
  std::uint64_t raw_rays = 0, bake_peak = 0;
  const auto run_bake = [&]() {
    const nmbake::Status s = nmbake::bake(o, report);
    if (!s) {
      std::fprintf(stderr, "nmbake-bench: %s\n", s.message().c_str());
      return false;
    }
    load.push_back(stage(report, "load"));
    build.push_back(stage(report, "build"));
    raster.push_back(stage(report, "raster"));
    trace.push_back(stage(report, "trace"));
    encode.push_back(stage(report, "encode"));
    write.push_back(stage(report, "write"));
    rest.push_back(stage(report, "prepare") + stage(report, "distances") + stage(report, "dilate"));
    total.push_back(report.total_seconds);
    return true;
  };
  // The first bake runs alone, so its peak RSS is the bake's own.
  if (!run_bake()) return 2;
  bake_peak = report.peak_rss_bytes;

  // Raw Embree: the same meshes, rays and packets. Each raw run follows a
  // bake, so a slow spell of the shared machine falls on both sides of a
  // pair, and "ratio" is the median of the pairs' ratios. The raw side loads
  // its own meshes and scene and frees them before the next bake, which
  // runs as it would alone.
  const auto run_raw = [&]() {
    nmbake::Mesh low_mesh, high_mesh;
    nmbake::LoadStats ls;
    nmbake::MeshStats ms;
    if (!nmbake::load_mesh(low, {}, low_mesh, ls) || !nmbake::load_mesh(high, {false, true}, high_mesh, ls)) {
      return false;
    }
    nmbake::prepare_low_normals(low_mesh, ms);
    nmbake::pad_for_embree(high_mesh);
    nmbake::SurfaceStats ss;
    const nmbake::LowSurface surface = nmbake::build_low_surface(low_mesh, nullptr, ss);
    nmbake::HighScene scene;
    if (!nmbake::HighScene::build(high_mesh, o.build_quality, false, scene, o.bvh_memory)) return false;
    nmbake::RayOptions rays;
    rays.front = report.front;
    rays.back = report.back;
    // The bake's bands of rows: the prebuilt packets of a whole 4096^2 x16
    // map would not fit in memory. Only the Embree calls are timed.
    const int rows = nmbake::band_rows(size, size, samples, band_samples);
    nmbake::TexelSamples ts;
    double seconds = 0.0;
    raw_rays = 0;
    for (int row = 0; row < size; row += rows) {
      nmbake::RasterStats rs;
      nmbake::rasterize(surface, size, size, samples, ts, rs, row, std::min(row + rows, size));
      const nmbake::RawTraceResult r = nmbake::trace_raw(scene, surface, ts, rays);
      seconds += r.seconds;
      raw_rays += r.rays;
    }
    raw.push_back(seconds);
    // bake rays/s over raw rays/s, for this pair
    ratio.push_back((static_cast<double>(report.trace.rays) / trace.back()) /
                    (static_cast<double>(raw_rays) / seconds));
    if (std::getenv("NMBAKE_BENCH_PAIRS")) {
      std::fprintf(stderr, "pair %zu: trace %.3f s raw %.3f s\n", raw.size(), trace.back(), seconds);
    }
    return true;
  };
  for (int i = 0; i < repeat; ++i) {
    if (i > 0 && !run_bake()) return 2;
    if (!run_raw()) {
      std::fprintf(stderr, "nmbake-bench: the raw baseline could not load or build the scene\n");
      return 2;
    }
  }
  // The ray rule's own cost: the trace stage with the defaults (banded cage,
  // misses retried) and with the old rule (averaged cage, no retry), on the
  // same scene and samples, band by band in the order ABBA, so that a slow
  // spell of the shared machine falls on both; per pass the ratio of the
  // sums, the median over the passes.
  std::vector<double> rule_new, rule_old, rule_ratio;
  std::uint64_t rule_retried = 0;
  if (compare_pairs > 0) {
    nmbake::Mesh low_mesh, high_mesh;
    nmbake::LoadStats ls;
    nmbake::MeshStats ms;
    if (!nmbake::load_mesh(low, {}, low_mesh, ls) || !nmbake::load_mesh(high, {false, true}, high_mesh, ls)) return 2;
    nmbake::prepare_low_normals(low_mesh, ms);
    nmbake::pad_for_embree(high_mesh);
    nmbake::SurfaceStats ss;
    nmbake::LowSurface surface = nmbake::build_low_surface(low_mesh, nullptr, ss);
    nmbake::HighScene scene;
    if (!nmbake::HighScene::build(high_mesh, o.build_quality, false, scene, o.bvh_memory)) return 2;
    nmbake::RayOptions rule[2];  // 0: the defaults, 1: the old rule
    rule[0].cage = nmbake::CageMode::banded;
    rule[0].front = rule[1].front = report.front;
    rule[0].back = rule[1].back = report.back;
    rule[0].retry_reach = report.retry_reach;
    rule[1].cage = nmbake::CageMode::averaged;
    nmbake::prepare_edge_band(surface, nmbake::edge_band_reach(rule[0]));
    const int rows = nmbake::band_rows(size, size, samples, band_samples);
    nmbake::TexelSamples ts;
    nmbake::Hits hits;
    for (int pass = 0; pass < compare_pairs; ++pass) {
      double seconds[2] = {0.0, 0.0};
      int band = 0;
      for (int row = 0; row < size; row += rows, ++band) {
        nmbake::RasterStats rs;
        nmbake::rasterize(surface, size, size, samples, ts, rs, row, std::min(row + rows, size));
        for (int k = 0; k < 2; ++k) {
          const int r = (band % 2 == 0) == (k == 0) ? 0 : 1;
          nmbake::TraceStats stats;
          const auto begin = std::chrono::steady_clock::now();
          nmbake::trace(scene, surface, ts, rule[r], hits, stats);
          seconds[r] += std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();
          if (r == 0 && pass == 0) rule_retried += stats.retried;
        }
      }
      rule_new.push_back(seconds[0]);
      rule_old.push_back(seconds[1]);
      rule_ratio.push_back(seconds[0] / seconds[1]);
      if (std::getenv("NMBAKE_BENCH_PAIRS")) {
        std::fprintf(stderr, "rule pass %d: trace %.4f s (banded, retry) vs %.4f s (averaged, no retry)\n", pass + 1,
                     seconds[0], seconds[1]);
      }
    }
  }
  std::filesystem::remove_all(dir);

  const double bake_rays_per_s = static_cast<double>(report.trace.rays) / median(trace);
  const double raw_rays_per_s = static_cast<double>(raw_rays) / median(raw);
  std::printf(
      "bench %-12s tris %9llu  map %5d x%-2d threads %d bvh %-7s %-6s | load %6.3f build %6.3f raster %6.3f trace %6.3f "
      "encode %6.3f write %6.3f rest %6.3f total %6.3f s | bake %6.2f Mrays/s raw %6.2f Mrays/s ratio %.2f | peak %6.0f MiB "
      "(%.0f B/tri)\n",
      label.c_str(), static_cast<unsigned long long>(report.high_triangles), size, samples, report.threads,
      report.compact_bvh ? "compact" : "fast", quality.c_str(),
      median(load), median(build), median(raster), median(trace), median(encode), median(write), median(rest), median(total),
      1e-6 * bake_rays_per_s, 1e-6 * raw_rays_per_s, median(ratio),
      static_cast<double>(bake_peak) / (1024.0 * 1024.0),
      static_cast<double>(bake_peak) / static_cast<double>(std::max<std::uint64_t>(1, report.high_triangles)));
  if (compare_pairs > 0) {
    std::printf("rule  %-12s map %5d x%-2d | trace %6.4f s (banded cage, retry: %llu retried) vs %6.4f s (averaged, "
                "no retry) | ratio %.3f (median of %d passes; min %.3f max %.3f)\n",
                label.c_str(), size, samples, median(rule_new), static_cast<unsigned long long>(rule_retried),
                median(rule_old), median(rule_ratio), compare_pairs,
                *std::min_element(rule_ratio.begin(), rule_ratio.end()),
                *std::max_element(rule_ratio.begin(), rule_ratio.end()));
  }
  return 0;
}
