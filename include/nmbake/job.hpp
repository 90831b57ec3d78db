// Job files: several bakes described in TOML (schema in README.md, example in
// scenes/moon.toml). Paths in a job file are relative to the job file's folder.
//
//   [defaults]                  # optional, applies to every [[bake]]
//   size = 2048                 # or width = .. / height = ..
//   samples = 4
//   [[bake]]
//   name = "moon"
//   low = "generated/moon_low.obj"
//   high = "generated/moon_high.ply"
//   outputs = ["out/moon_normal.png", { path = "out/moon_normal.exr", format = "exr-half" }]
//   report = "out/moon_report.json"
//
// Keys of [defaults] and [[bake]]: size, width, height, samples, space,
// green, front, back, hit, cage_mode, edge_band, retry_misses, ignore_backfaces, high_normals, padding,
// build_quality, bvh, cage, max_memory (bytes or "8G"), match, unmatched,
// low_suffix, high_suffix, cage_suffix, cache, and the map set's maps
// (["normal", "ao"] or "normal,ao"), height_range, curvature_range ("auto" or
// a number), ao_rays, ao_distance, thickness_rays, thickness_distance
// (a number, "N%" or "auto"), id_source ("auto", "part" or "material"); [[bake]] alone: name, low,
// high, outputs, report, debug_dump, and [[bake.group]] tables (name, low =
// [part names], high = [part names]: explicit bake groups, parts.hpp).
// Unknown keys are errors (a typo must not silently bake with a default).
#pragma once

#include <string>
#include <vector>

#include "nmbake/bake_options.hpp"

namespace nmbake {

struct BakeJob {
  std::string name;
  BakeOptions options;
  std::string report_path;  // empty: no JSON report
  std::string cache_dir;    // `cache = "DIR"`: the bake cache (cache.hpp); empty: none
};

Status load_job_file(const std::string& path, std::vector<BakeJob>& jobs);

}  // namespace nmbake
