// A bake's outputs: every output once per map (bake_options.hpp), and the
// write stage of a map set (bake.hpp).
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstddef>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "image/quantise.hpp"
#include "nmbake/bake.hpp"
#include "nmbake/bake_options.hpp"
#include "nmbake/image.hpp"
#include "nmbake/maps.hpp"
#include "nmbake/sets.hpp"
#include "nmbake/textures.hpp"
#include "nmbake/udim.hpp"

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

PixelFormat pack_format(const std::string& path) {
  PixelFormat format = PixelFormat::png8;
  if (!pixel_format_from_path(path, format) || format == PixelFormat::png16) return PixelFormat::png8;
  return format;
}

Status write_pack_files(MapSet& maps, const std::vector<PackSpec>& packs, int udim_tile, bool dither,
                        std::vector<std::string>& written) {
  for (const PackSpec& pack : packs) {
    const std::string path = udim_path(pack.path, udim_tile);
    const PixelFormat format = pack_format(path);
    const bool integer = !is_float_format(format);
    const float steps = format == PixelFormat::tiff16 ? 65535.0f : 255.0f;
    const bool eight = is_8bit(format);
    Image out;
    out.channels = static_cast<int>(pack.channels.size());
    for (const PackChannel& c : pack.channels) {
      if (c.constant) continue;
      out.width = maps.image(c.map).width;
      out.height = maps.image(c.map).height;
    }
    out.pixels.assign(static_cast<std::size_t>(out.width) * out.height * out.channels, 0.0f);
    for (int k = 0; k < out.channels; ++k) {
      const PackChannel& c = pack.channels[static_cast<std::size_t>(k)];
      const Image* source = c.constant ? nullptr : &maps.image(c.map);
      float scale = 1.0f, offset = 0.0f;
      if (source != nullptr) maps.integer_mapping(c.map, scale, offset);
      const bool srgb = source != nullptr && map_traits(c.map).srgb;
      tbb::parallel_for(0, out.height, [&](int y) {
        for (int x = 0; x < out.width; ++x) {
          float v = c.value;
          if (source != nullptr) {
            v = source->at(x, y)[c.component];
            if (integer) {
              // As the map's own integer file stores it (WriteOptions).
              v = v * scale + offset;
              if (srgb) v = linear_to_srgb(v);
            }
          }
          if (c.invert) v = 1.0f - std::clamp(v, 0.0f, 1.0f);
          if (integer) {
            // Quantised here as the map's own file is, dithered with its own
            // channel's pattern, so the channel is the map's file's bytes;
            // the writer below gets exact steps and no dither.
            const auto component = static_cast<std::uint32_t>(c.component);
            const std::uint32_t q = eight && dither && !c.constant
                                        ? detail::quantise_dithered(v, steps, static_cast<std::uint32_t>(x),
                                                                    static_cast<std::uint32_t>(y), component)
                                        : detail::quantise(v, steps);
            v = static_cast<float>(q) / steps;
          }
          out.at(x, y)[k] = v;
        }
      });
    }
    NMBAKE_TRY(write_image(out, path, format, WriteOptions{}));
    written.push_back(path);
  }
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

void resolve_low_token(BakeOptions& o) {
  const std::string stem = std::filesystem::path(o.low_path).stem().string();
  for (OutputSpec& out : o.outputs) out.path = replace_token(out.path, kLowToken, stem);
  for (PackSpec& pack : o.packs) pack.path = replace_token(pack.path, kLowToken, stem);
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
