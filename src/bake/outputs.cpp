// A bake's outputs: every output once per map (bake_options.hpp), and the
// write stage of a map set (bake.hpp).
#include <tbb/parallel_for.h>

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "nmbake/bake.hpp"
#include "nmbake/bake_options.hpp"
#include "nmbake/image.hpp"
#include "nmbake/maps.hpp"

namespace nmbake {

Status write_map_files(MapSet& maps, const std::vector<MapOutput>& files, bool dither) {
  std::vector<Status> written(files.size());
  tbb::parallel_for(std::size_t{0}, files.size(), [&](std::size_t i) {
    const MapOutput& out = files[i];
    WriteOptions options;
    options.dither = dither;
    maps.integer_mapping(out.map, options.scale, options.offset);
    options.srgb = map_traits(out.map).srgb;
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

}  // namespace nmbake
