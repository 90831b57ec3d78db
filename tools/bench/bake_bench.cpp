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
//
// The map set (maps.hpp):
//   --map LIST             bake these maps (PNG, each map's default depth);
//   --versus LIST          also bake this map set, alternating with the
//                          first, and print the median ratio of the pairs'
//                          whole-bake times (e.g. --map normal,height,position,
//                          curvature --versus normal);
//   --ao-rays N            AO rays per sample; with ao in --map, the raw side
//                          also fires the bake's AO rays as the same packets
//                          (trace_occlusion_raw: only rtcOccluded16 timed) and
//                          the line gives AO rays/s of the bake's occlusion
//                          stage against it.
#include <tbb/global_control.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "nmbake/bake.hpp"
#include "nmbake/job.hpp"
#include "nmbake/occlusion.hpp"

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
  std::string maps_text = "normal", versus_text;
  int ao_rays = 64;
  int compare_pairs = 0;
  CLI::App app{"nmbake-bench: a whole bake beside raw Embree on the same rays"};
  app.add_option("--map", maps_text, "maps to bake (comma list)")->capture_default_str();
  app.add_option("--versus", versus_text,
                 "a second map set baked alternately: the ratio of whole-bake times");
  app.add_option("--ao-rays", ao_rays, "AO rays per sample")->capture_default_str();
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
  app.add_option(
         "--compare-old-rule", compare_pairs,
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
  o.high_paths = {high};
  o.width = o.height = size;
  o.samples = samples;
  o.band_samples = band_samples;
  o.outputs = {{(dir / "map_<MAP>.png").string(), nmbake::PixelFormat::png16}};
  o.maps.clear();
  if (const nmbake::Status s = nmbake::parse_map_list(maps_text, o.maps); !s) {
    std::fprintf(stderr, "nmbake-bench: --map: %s\n", s.message().c_str());
    return 2;
  }
  o.ao_rays = ao_rays;
  nmbake::BakeOptions versus = o;
  if (!versus_text.empty()) {
    versus.maps.clear();
    if (const nmbake::Status s = nmbake::parse_map_list(versus_text, versus.maps); !s) {
      std::fprintf(stderr, "nmbake-bench: --versus: %s\n", s.message().c_str());
      return 2;
    }
  }
  const bool with_ao = std::find(o.maps.begin(), o.maps.end(), nmbake::MapKind::ao) != o.maps.end();
  if (!nmbake::parse_word(quality, o.build_quality)) {
    std::fprintf(stderr, "nmbake-bench: --build-quality %s: expected low, medium or high\n", quality.c_str());
    return 2;
  }
  if (!nmbake::parse_word(bvh, o.bvh_memory)) {
    std::fprintf(stderr, "nmbake-bench: --bvh %s: expected auto, fast or compact\n", bvh.c_str());
    return 2;
  }

  // rest: prepare (normals, tangents) + distances (auto estimate) + dilate.
  std::vector<double> load, build, raster, trace, encode, write, rest, total, raw, ratio;
  std::vector<double> occlusion, raw_occlusion, occlusion_ratio, versus_total, versus_ratio;
  std::uint64_t occlusion_rays = 0, raw_occlusion_rays = 0;
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
    occlusion.push_back(stage(report, "occlusion"));
    occlusion_rays = 0;
    for (const nmbake::MapReport& m : report.map_reports) {
      if (m.map == nmbake::MapKind::ao) occlusion_rays += static_cast<std::uint64_t>(m.figure("rays"));
    }
    return true;
  };
  // The other map set, right after: its time against this bake's.
  const auto run_versus = [&]() {
    if (versus_text.empty()) return true;
    nmbake::BakeReport other;
    const nmbake::Status s = nmbake::bake(versus, other);
    if (!s) {
      std::fprintf(stderr, "nmbake-bench: %s\n", s.message().c_str());
      return false;
    }
    versus_total.push_back(other.total_seconds);
    versus_ratio.push_back(total.back() / other.total_seconds);
    if (std::getenv("NMBAKE_BENCH_PAIRS")) {
      std::fprintf(stderr, "pair %zu: maps %.3f s versus %.3f s\n", versus_total.size(), total.back(),
                   other.total_seconds);
    }
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
    nmbake::normalize_normals(high_mesh, ms);  // as the bake prepares them: the AO frames are the same
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
    double seconds = 0.0, occlusion_seconds = 0.0;
    raw_rays = 0;
    raw_occlusion_rays = 0;
    nmbake::OcclusionOptions ao;
    ao.rays = ao_rays;
    ao.distance = nmbake::kAutoMapDistancePercent * 0.01f * report.low_diagonal;
    for (int row = 0; row < size; row += rows) {
      nmbake::RasterStats rs;
      nmbake::rasterize(surface, size, size, samples, ts, rs, row, std::min(row + rows, size));
      const nmbake::RawTraceResult r = nmbake::trace_raw(scene, surface, ts, rays);
      seconds += r.seconds;
      raw_rays += r.rays;
      if (with_ao) {
        // The AO rays start at the bake's hits: trace them (not timed), then
        // fire the AO packets with only rtcOccluded16 timed.
        nmbake::Hits hits;
        nmbake::TraceStats trace_stats;
        nmbake::trace(scene, surface, ts, rays, hits, trace_stats);
        const nmbake::RawTraceResult a = nmbake::trace_occlusion_raw(scene, high_mesh, surface, ts, hits, ao);
        occlusion_seconds += a.seconds;
        raw_occlusion_rays += a.rays;
      }
    }
    if (with_ao) {
      raw_occlusion.push_back(occlusion_seconds);
      occlusion_ratio.push_back((static_cast<double>(occlusion_rays) / occlusion.back()) /
                                (static_cast<double>(raw_occlusion_rays) / occlusion_seconds));
      if (std::getenv("NMBAKE_BENCH_PAIRS")) {
        std::fprintf(stderr, "pair %zu: occlusion %.3f s raw %.3f s (%llu / %llu rays)\n",
                     raw_occlusion.size(), occlusion.back(), occlusion_seconds,
                     static_cast<unsigned long long>(occlusion_rays),
                     static_cast<unsigned long long>(raw_occlusion_rays));
      }
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
    if (!run_versus()) return 2;
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
    if (!nmbake::load_mesh(low, {}, low_mesh, ls) || !nmbake::load_mesh(high, {false, true}, high_mesh, ls))
      return 2;
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
        std::fprintf(stderr, "rule pass %d: trace %.4f s (banded, retry) vs %.4f s (averaged, no retry)\n",
                     pass + 1, seconds[0], seconds[1]);
      }
    }
  }
  std::filesystem::remove_all(dir);

  const double bake_rays_per_s = static_cast<double>(report.trace.rays) / median(trace);
  const double raw_rays_per_s = static_cast<double>(raw_rays) / median(raw);
  std::printf(
      "bench %-12s tris %9llu  map %5d x%-2d threads %d bvh %-7s %-6s | load %6.3f build %6.3f raster %6.3f "
      "trace %6.3f "
      "encode %6.3f write %6.3f rest %6.3f total %6.3f s | bake %6.2f Mrays/s raw %6.2f Mrays/s ratio %.2f | "
      "peak %6.0f MiB "
      "(%.0f B/tri)\n",
      label.c_str(), static_cast<unsigned long long>(report.high_triangles), size, samples, report.threads,
      report.compact_bvh ? "compact" : "fast", quality.c_str(), median(load), median(build), median(raster),
      median(trace), median(encode), median(write), median(rest), median(total), 1e-6 * bake_rays_per_s,
      1e-6 * raw_rays_per_s, median(ratio), static_cast<double>(bake_peak) / (1024.0 * 1024.0),
      static_cast<double>(bake_peak) /
          static_cast<double>(std::max<std::uint64_t>(1, report.high_triangles)));
  if (!versus_text.empty()) {
    std::printf(
        "bench %-12s maps %s: total %.3f s; versus %s: total %.3f s; ratio %.3f (median of %zu pairs)\n",
        label.c_str(), maps_text.c_str(), median(total), versus_text.c_str(), median(versus_total),
        median(versus_ratio), versus_ratio.size());
  }
  if (with_ao) {
    std::printf(
        "bench %-12s ao %d rays/sample: occlusion %.3f s, %.2f Mrays/s; raw rtcOccluded16 %.3f s, %.2f "
        "Mrays/s; "
        "ratio %.2f (median of %zu pairs); %llu AO rays; whole bake %.3f s\n",
        label.c_str(), ao_rays, median(occlusion),
        1e-6 * static_cast<double>(occlusion_rays) / median(occlusion), median(raw_occlusion),
        1e-6 * static_cast<double>(raw_occlusion_rays) / median(raw_occlusion), median(occlusion_ratio),
        occlusion_ratio.size(), static_cast<unsigned long long>(occlusion_rays), median(total));
  }
  if (compare_pairs > 0) {
    std::printf(
        "rule  %-12s map %5d x%-2d | trace %6.4f s (banded cage, retry: %llu retried) vs %6.4f s (averaged, "
        "no retry) | ratio %.3f (median of %d passes; min %.3f max %.3f)\n",
        label.c_str(), size, samples, median(rule_new), static_cast<unsigned long long>(rule_retried),
        median(rule_old), median(rule_ratio), compare_pairs,
        *std::min_element(rule_ratio.begin(), rule_ratio.end()),
        *std::max_element(rule_ratio.begin(), rule_ratio.end()));
  }
  return 0;
}
