// Bake keys, tile files and the merge (task.hpp).
//
// Key: XXH3-128 (xxHash 0.8, Yann Collet) over, in order, the canonical
// option text and, for each of low, high, cage, the file's length and bytes.
//
// Tile file, little endian:
//   "NMBTILE2" | key (high, low: u64) | i32 width, height, row_begin,
//   row_end, index, count, padding, dither, output count | per output: u8 format,
//   u32 path length, path | f32 pixels[rows * width * 3] | u8
//   coverage[rows * width] | u64 XXH3-64 of everything before it.
// The sizes are checked against the file's length before anything is
// allocated, and the trailing hash finds a torn or altered file.
#include "nmbake/task.hpp"

#include "nmbake/job.hpp"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <nlohmann/json.hpp>
#include <tbb/parallel_for.h>
#include <xxhash.h>

#include "nmbake/cleanup.hpp"
#include "nmbake/preset.hpp"
#include "nmbake/udim.hpp"

namespace nmbake {

static_assert(std::endian::native == std::endian::little, "tile files are written in the machine's byte order");

std::string BakeKey::hex() const {
  char text[33];
  std::snprintf(text, sizeof text, "%016llx%016llx", static_cast<unsigned long long>(high),
                static_cast<unsigned long long>(low));
  return text;
}

std::string bake_key_text(const BakeOptions& o) {
  std::string t;
  const auto line = [&](const char* name, const std::string& value) {
    t += name;
    t += ' ';
    t += value;
    t += '\n';
  };
  const auto number = [](double v) {
    char text[32];
    std::snprintf(text, sizeof text, "%.9g", v);
    return std::string(text);
  };
  line("nmbake", kNmbakeVersion);
  line("size", std::to_string(o.width) + "x" + std::to_string(o.height));
  if (o.adaptive) {
    // The thresholds are part of the rule: a change of them changes bytes.
    line("samples", "adaptive " + std::to_string(o.adaptive_options.max_samples) + " " +
                        number(o.adaptive_options.normal_threshold) + " " +
                        number(o.adaptive_options.depth_threshold) + " " +
                        number(o.adaptive_options.border_threshold) + " " +
                        number(o.adaptive_options.spread_threshold));
  } else {
    line("samples", std::to_string(o.samples));
  }
  line("space", o.space == NormalSpace::tangent ? "tangent" : "object");
  line("green", o.green == GreenChannel::up ? "up" : "down");
  for (const auto& [name, d] : {std::pair{"front", o.front}, std::pair{"back", o.back}}) {
    line(name, d.kind == Distance::Kind::automatic ? std::string("auto")
               : d.kind == Distance::Kind::percent ? number(d.value) + "%"
                                                    : number(d.value));
  }
  line("hit", o.hit == HitRule::first ? "first" : "nearest");
  line("cage_mode", to_string(o.cage_mode));
  if (o.cage_mode == CageMode::banded) line("edge_band", number(o.edge_band));
  line("retry_misses", o.retry_misses == BakeOptions::Retry::on    ? "on"
                       : o.retry_misses == BakeOptions::Retry::off ? "off"
                                                                   : "auto");
  line("cage", o.cage_path.empty() ? "none" : "mesh");
  line("ignore_backfaces", o.ignore_backfaces ? "1" : "0");
  line("high_normals", o.high_normals == HighNormals::smooth ? "smooth" : "face");
  line("tangent_encode", o.tangent_encode == TangentEncode::inverse ? "inverse" : "transpose");
  line("tangent_basis", to_string(o.tangent_basis));
  // Outputs as engines want them: the preset, and what it resolved to after
  // explicit flags (the rules are what change bytes; the name errs on the
  // side of a miss).
  line("preset", o.preset.empty() ? "none" : o.preset);
  line("decode", std::string(to_string(o.decode.bitangent)) + " " + frame_rule_name(o.decode.unit_frame) + " " +
                     blue_rule_name(o.decode.rebuild_blue));
  line("dither", o.dither ? "on" : "off");
  // The BVH's quality and layout do not choose other hits, but a key errs on
  // the side of a miss.
  line("build_quality", std::to_string(static_cast<int>(o.build_quality)));
  line("bvh", std::to_string(static_cast<int>(o.bvh_memory)));
  line("padding", std::to_string(o.padding));
  line("unwrap_gutter", std::to_string(o.unwrap_gutter));
  line("match", to_string(o.match.mode));
  line("suffixes", o.match.low_suffix + " " + o.match.high_suffix + " " + o.match.cage_suffix);
  line("unmatched", to_string(o.match.unmatched));
  for (const GroupSpec& g : o.match.groups) {
    std::string text = g.name + " |";
    for (const std::string& n : g.low) text += " " + n;
    text += " |";
    for (const std::string& n : g.high) text += " " + n;
    line("group", text);
  }
  // The map set, only when it is more than the normal map (the key of a
  // normal bake is the key it had before maps existed): the maps in order,
  // the options of those baked, and whether an output's format was given
  // (a map's own depth for `.png` otherwise).
  const bool map_set = o.maps.size() != 1 || o.maps.front() != MapKind::normal;
  for (const OutputSpec& out : o.outputs) {
    line("output", std::string(to_string(out.format)) + (has_udim_token(out.path) ? " udim" : "") +
                       (map_set && out.format_given ? " given" : ""));
  }
  if (map_set) {
    std::string names;
    for (const MapKind m : o.maps) {
      if (!names.empty()) names += ',';
      names += to_string(m);
    }
    line("maps", names);
    const auto has = [&](MapKind m) { return std::find(o.maps.begin(), o.maps.end(), m) != o.maps.end(); };
    const auto distance = [&](const Distance& d) {
      return d.kind == Distance::Kind::automatic ? std::string("auto")
             : d.kind == Distance::Kind::percent ? number(d.value) + "%"
                                                  : number(d.value);
    };
    if (has(MapKind::height)) line("height_range", o.height_range > 0.0f ? number(o.height_range) : "auto");
    if (has(MapKind::curvature)) line("curvature_range", o.curvature_range > 0.0f ? number(o.curvature_range) : "auto");
    if (has(MapKind::id)) line("id_source", to_string(o.id_source));
    if (has(MapKind::ao) || has(MapKind::bent_normal)) {
      line("ao_rays", std::to_string(o.ao_rays));
      line("ao_distance", distance(o.ao_distance));
    }
    if (has(MapKind::thickness)) {
      line("thickness_rays", std::to_string(o.thickness_rays));
      line("thickness_distance", distance(o.thickness_distance));
    }
  }
  return t;
}

namespace {

// Streams a file into the hash; its length first, so that two files cannot
// trade bytes across their border.
Status hash_file(XXH3_state_t* state, const std::string& path, const char* role) {
  if (path.empty()) {
    const std::uint64_t none = ~std::uint64_t{0};
    XXH3_128bits_update(state, &none, sizeof none);
    return Status::ok();
  }
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return Status::bad_input(path + ": cannot read the " + role + " mesh: " + std::strerror(errno));
  struct stat info {};
  if (::fstat(fd, &info) != 0 || !S_ISREG(info.st_mode)) {
    ::close(fd);
    return Status::bad_input(path + ": the " + role + " mesh is not a regular file");
  }
  const auto size = static_cast<std::uint64_t>(info.st_size);
  XXH3_128bits_update(state, &size, sizeof size);
  constexpr std::size_t kChunk = std::size_t{1} << 20;
  const auto buffer = std::make_unique_for_overwrite<char[]>(kChunk);
  std::uint64_t total = 0;
  for (;;) {
    const ssize_t got = ::read(fd, buffer.get(), kChunk);
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) {
      const int error = errno;
      ::close(fd);
      return Status::bad_input(path + ": cannot read the " + role + " mesh: " + std::strerror(error));
    }
    if (got == 0) break;
    XXH3_128bits_update(state, buffer.get(), static_cast<std::size_t>(got));
    total += static_cast<std::uint64_t>(got);
  }
  ::close(fd);
  if (total != size) return Status::bad_input(path + ": the " + role + " mesh changed while it was read");
  return Status::ok();
}

}  // namespace

Status bake_key(const BakeOptions& o, BakeKey& key) {
  std::unique_ptr<XXH3_state_t, decltype(&XXH3_freeState)> state(XXH3_createState(), &XXH3_freeState);
  NMBAKE_CHECK(state != nullptr, "xxHash state");
  XXH3_128bits_reset(state.get());
  const std::string text = bake_key_text(o);
  XXH3_128bits_update(state.get(), text.data(), text.size());
  NMBAKE_TRY(hash_file(state.get(), o.low_path, "low"));
  NMBAKE_TRY(hash_file(state.get(), o.high_path, "high"));
  NMBAKE_TRY(hash_file(state.get(), o.cage_path, "cage"));
  const XXH128_hash_t h = XXH3_128bits_digest(state.get());
  key.high = h.high64;
  key.low = h.low64;
  return Status::ok();
}

void tile_rows(int height, int index, int count, int& begin, int& end) {
  NMBAKE_CHECK(count > 0 && index >= 0 && index < count, "tile index in range");
  const int units = (height + kRasterTileSize - 1) / kRasterTileSize;  // 32-row raster tiles
  const auto split = [&](int i) {
    return static_cast<int>(static_cast<std::int64_t>(units) * i / count) * kRasterTileSize;
  };
  begin = std::min(height, split(index));
  end = std::min(height, split(index + 1));
}

bool parse_tile_spec(const std::string& text, int& index, int& count) {
  const std::size_t slash = text.find('/');
  if (slash == std::string::npos || slash == 0 || slash + 1 == text.size()) return false;
  int i = 0, n = 0;
  for (std::size_t k = 0; k < text.size(); ++k) {
    if (k == slash) continue;
    if (text[k] < '0' || text[k] > '9') return false;
  }
  try {
    if (slash > 6 || text.size() - slash - 1 > 6) return false;
    i = std::stoi(text.substr(0, slash));
    n = std::stoi(text.substr(slash + 1));
  } catch (...) {
    return false;
  }
  if (n < 1 || n > 4096 || i < 1 || i > n) return false;
  index = i - 1;
  count = n;
  return true;
}

namespace {

// "2": the dither flag joined the header (a "1" file is refused as one of another build).
constexpr char kMagic[8] = {'N', 'M', 'B', 'T', 'I', 'L', 'E', '2'};

template <typename T>
void put(std::string& out, const T& value) {
  out.append(reinterpret_cast<const char*>(&value), sizeof value);
}

// XXH3-64 of the header and the tile's arrays: the trailer of a tile file.
std::uint64_t tile_checksum(const std::string& header, const TileData& tile) {
  std::unique_ptr<XXH3_state_t, decltype(&XXH3_freeState)> state(XXH3_createState(), &XXH3_freeState);
  NMBAKE_CHECK(state != nullptr, "xxHash state");
  XXH3_64bits_reset(state.get());
  XXH3_64bits_update(state.get(), header.data(), header.size());
  XXH3_64bits_update(state.get(), tile.pixels.data(), tile.pixels.size() * sizeof(float));
  XXH3_64bits_update(state.get(), tile.coverage.data(), tile.coverage.size());
  return XXH3_64bits_digest(state.get());
}

}  // namespace

Status write_tile(const std::string& path, const TileData& tile) {
  const std::size_t rows = static_cast<std::size_t>(tile.row_end - tile.row_begin);
  NMBAKE_CHECK(tile.pixels.size() == rows * tile.width * 3 && tile.coverage.size() == rows * tile.width,
               "tile arrays of its rows");
  std::string header(kMagic, sizeof kMagic);
  put(header, tile.key.high);
  put(header, tile.key.low);
  for (const int v : {tile.width, tile.height, tile.row_begin, tile.row_end, tile.index, tile.count, tile.padding,
                      tile.dither ? 1 : 0, static_cast<int>(tile.outputs.size())}) {
    put(header, static_cast<std::int32_t>(v));
  }
  for (const OutputSpec& out : tile.outputs) {
    put(header, static_cast<std::uint8_t>(out.format));
    put(header, static_cast<std::uint32_t>(out.path.size()));
    header += out.path;
  }
  const std::uint64_t check = tile_checksum(header, tile);

  const std::string_view pixels(reinterpret_cast<const char*>(tile.pixels.data()), tile.pixels.size() * sizeof(float));
  const std::string_view coverage(reinterpret_cast<const char*>(tile.coverage.data()), tile.coverage.size());
  const std::string_view trailer(reinterpret_cast<const char*>(&check), sizeof check);
  return write_file_atomically(path, {header, pixels, coverage, trailer}, "the tile file");
}

Status read_tile(const std::string& path, TileData& tile) {
  tile = TileData{};
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::bad_input(path + ": cannot open the tile file: " + std::strerror(errno));
  in.seekg(0, std::ios::end);
  const auto file_size = static_cast<std::uint64_t>(in.tellg());
  in.seekg(0);
  const auto bad = [&](const std::string& why) { return Status::bad_input(path + ": not a complete nmbake tile file: " + why); };
  std::string header(sizeof kMagic + 16 + 9 * 4, '\0');
  if (!in.read(header.data(), static_cast<std::streamsize>(header.size()))) return bad("too short");
  if (std::memcmp(header.data(), kMagic, sizeof kMagic) != 0) return bad("wrong magic bytes");
  const char* p = header.data() + sizeof kMagic;
  std::memcpy(&tile.key.high, p, 8);
  std::memcpy(&tile.key.low, p + 8, 8);
  std::int32_t v[9];
  std::memcpy(v, p + 16, sizeof v);
  tile.width = v[0];
  tile.height = v[1];
  tile.row_begin = v[2];
  tile.row_end = v[3];
  tile.index = v[4];
  tile.count = v[5];
  tile.padding = v[6];
  const std::int32_t dither = v[7];
  tile.dither = dither == 1;
  const std::int32_t output_count = v[8];
  if (tile.width <= 0 || tile.height <= 0 || tile.width > 65536 || tile.height > 65536 || tile.row_begin < 0 ||
      tile.row_end < tile.row_begin || tile.row_end > tile.height || tile.count < 1 || tile.count > 4096 ||
      tile.index < 0 || tile.index >= tile.count || tile.padding < 0 || (dither != 0 && dither != 1) ||
      output_count < 0 || output_count > 64) {
    return bad("header values out of range");
  }
  for (std::int32_t i = 0; i < output_count; ++i) {
    std::uint8_t format = 0;
    std::uint32_t length = 0;
    if (!in.read(reinterpret_cast<char*>(&format), 1) || !in.read(reinterpret_cast<char*>(&length), 4)) return bad("too short");
    if (format > static_cast<std::uint8_t>(PixelFormat::tga8) || length > 65536) return bad("bad output entry");
    OutputSpec out;
    out.format = static_cast<PixelFormat>(format);
    out.path.resize(length);
    if (!in.read(out.path.data(), length)) return bad("too short");
    header.append(reinterpret_cast<const char*>(&format), 1);
    header.append(reinterpret_cast<const char*>(&length), 4);
    header += out.path;
    tile.outputs.push_back(std::move(out));
  }
  const std::uint64_t texels = static_cast<std::uint64_t>(tile.row_end - tile.row_begin) * tile.width;
  const std::uint64_t expected = header.size() + texels * 13 + 8;
  if (expected != file_size) {
    return bad(std::to_string(file_size) + " bytes where the header says " + std::to_string(expected));
  }
  tile.pixels.resize(texels * 3);
  tile.coverage.resize(texels);
  std::uint64_t check = 0;
  in.read(reinterpret_cast<char*>(tile.pixels.data()), static_cast<std::streamsize>(texels * 12));
  in.read(reinterpret_cast<char*>(tile.coverage.data()), static_cast<std::streamsize>(texels));
  in.read(reinterpret_cast<char*>(&check), sizeof check);
  if (!in) return bad("too short");
  if (tile_checksum(header, tile) != check) return bad("its checksum does not match (a torn or altered file)");
  for (const std::uint8_t c : tile.coverage) {
    if (c > 1) return bad("coverage values other than 0 and 1");
  }
  return Status::ok();
}

std::string MergeReport::to_json() const {
  nlohmann::ordered_json j;
  j["key"] = key.hex();
  j["width"] = width;
  j["height"] = height;
  j["tiles"] = tiles;
  j["outputs"] = outputs;
  j["dilate_filled_texels"] = dilate.filled_texels;
  j["dilate_fallback_texels"] = dilate.fallback_texels;
  j["seconds"] = {{"read", read_seconds}, {"dilate", dilate_seconds}, {"write", write_seconds}};
  return j.dump(2) + "\n";
}

Status merge_tiles(const std::vector<std::string>& tile_paths, const std::vector<OutputSpec>& outputs,
                   MergeReport& report) {
  using Clock = std::chrono::steady_clock;
  report = MergeReport{};
  if (tile_paths.empty()) return Status::bad_input("merge: no tile files given");
  auto begin = Clock::now();
  TileData first;
  NMBAKE_TRY(read_tile(tile_paths.front(), first));
  const int width = first.width, height = first.height, count = first.count;
  if (static_cast<int>(tile_paths.size()) != count) {
    return Status::bad_input(tile_paths.front() + ": the bake has " + std::to_string(count) + " tiles, " +
                             std::to_string(tile_paths.size()) + " tile files were given");
  }
  Image image;
  image.width = width;
  image.height = height;
  image.channels = 3;
  image.pixels.resize(static_cast<std::size_t>(width) * height * 3);
  std::vector<std::uint8_t> coverage(static_cast<std::size_t>(width) * height, 0);
  std::vector<std::string> seen(static_cast<std::size_t>(count));
  for (std::size_t i = 0; i < tile_paths.size(); ++i) {
    TileData tile;
    if (i == 0) {
      tile = std::move(first);
    } else {
      NMBAKE_TRY(read_tile(tile_paths[i], tile));
    }
    const std::string& path = tile_paths[i];
    if (!(tile.key == report.key) && i > 0) {
      return Status::bad_input(path + ": a tile of another bake (key " + tile.key.hex() + ", not " + report.key.hex() + ")");
    }
    report.key = tile.key;
    if (tile.width != width || tile.height != height || tile.count != count || tile.padding != first.padding ||
        tile.dither != first.dither) {
      return Status::bad_input(path + ": a tile of another bake (size, tile count, padding or dithering differ)");
    }
    if (!seen[tile.index].empty()) {
      return Status::bad_input(path + ": tile " + std::to_string(tile.index + 1) + "/" + std::to_string(count) +
                               " is given twice (also " + seen[tile.index] + ")");
    }
    seen[tile.index] = path;
    int b = 0, e = 0;
    tile_rows(height, tile.index, count, b, e);
    if (tile.row_begin != b || tile.row_end != e) return Status::bad_input(path + ": its rows are not those of its tile");
    std::copy(tile.pixels.begin(), tile.pixels.end(), image.pixels.begin() + static_cast<std::ptrdiff_t>(b) * width * 3);
    std::copy(tile.coverage.begin(), tile.coverage.end(), coverage.begin() + static_cast<std::ptrdiff_t>(b) * width);
    if (i == 0) {
      first.padding = tile.padding;
      first.dither = tile.dither;
      first.outputs = tile.outputs;
    }
  }
  report.read_seconds = std::chrono::duration<double>(Clock::now() - begin).count();
  const std::vector<OutputSpec>& targets = outputs.empty() ? first.outputs : outputs;
  if (targets.empty()) return Status::bad_input("merge: no output map given (-o) and the tiles name none");
  for (const OutputSpec& out : targets) {
    if (const Status writer = check_image_writer(out.format); !writer) return Status::internal(out.path + ": " + writer.message());
  }
  report.width = width;
  report.height = height;
  report.tiles = count;
  begin = Clock::now();
  dilate(image, coverage, first.padding, report.dilate);
  report.dilate_seconds = std::chrono::duration<double>(Clock::now() - begin).count();
  begin = Clock::now();
  std::vector<Status> written(targets.size());
  tbb::parallel_for(std::size_t{0}, targets.size(),
                    [&](std::size_t i) {
                      written[i] = write_image(image, targets[i].path, targets[i].format, WriteOptions{first.dither});
                    });
  for (const Status& s : written) NMBAKE_TRY(s);
  report.write_seconds = std::chrono::duration<double>(Clock::now() - begin).count();
  for (const OutputSpec& out : targets) report.outputs.push_back(out.path);
  return Status::ok();
}

}  // namespace nmbake
