// The map set (maps.hpp): names, traits, the <MAP> token, and MapSet, which
// runs every map's module band by band and hands the write stage its images.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <glm/geometric.hpp>
#include <unordered_map>

#include "base/huge_pages.hpp"
#include "maps/modules.hpp"
#include "nmbake/maps.hpp"

namespace nmbake {

Status parse_map_list(const std::string& text, std::vector<MapKind>& out) {
  std::size_t begin = 0;
  bool any = false;
  while (begin <= text.size()) {
    std::size_t end = text.find(',', begin);
    if (end == std::string::npos) end = text.size();
    std::string word = text.substr(begin, end - begin);
    word.erase(0, word.find_first_not_of(" \t"));
    word.erase(word.find_last_not_of(" \t") + 1);
    begin = end + 1;
    if (word.empty()) continue;
    MapKind map = MapKind::normal;
    if (!parse_word(word, map)) {
      return Status::bad_input("unknown map '" + printable_text(word) + "': " + expected_words<MapKind>());
    }
    any = true;
    if (std::find(out.begin(), out.end(), map) == out.end()) out.push_back(map);
  }
  if (!any) return Status::bad_input("no map named in '" + printable_text(text) + "'");
  return Status::ok();
}

std::string map_list_text(const std::vector<MapKind>& maps) {
  std::string text;
  for (const MapKind m : maps) {
    if (!text.empty()) text += ", ";
    text += to_string(m);
  }
  return text;
}

MapTraits map_traits(MapKind map) {
  MapTraits t;
  switch (map) {
    case MapKind::normal:
    case MapKind::object_normal:
      t.dilate = DilateMode::unit_vector;
      break;
    case MapKind::bent_normal:
      t.dilate = DilateMode::unit_vector;
      t.occlusion_rays = true;
      break;
    case MapKind::height:
      t.channels = 1;
      break;
    case MapKind::ao:
      t.channels = 1;
      t.png_format = PixelFormat::png8;
      t.occlusion_rays = true;
      break;
    case MapKind::curvature:
      t.channels = 1;
      t.png_format = PixelFormat::png8;
      break;
    case MapKind::thickness:
      t.channels = 1;
      t.png_format = PixelFormat::png8;
      t.thickness_rays = true;
      break;
    case MapKind::position:
      break;
    case MapKind::miss:
      t.channels = 1;
      t.png_format = PixelFormat::png8;
      t.dilate = DilateMode::nearest;
      break;
    case MapKind::vertex_color:
      t.png_format = PixelFormat::png8;
      break;
    case MapKind::id:
      t.png_format = PixelFormat::png8;
      t.dilate = DilateMode::nearest;
      break;
    case MapKind::base_color:
    case MapKind::emissive:
      t.png_format = PixelFormat::png8;
      t.srgb = true;
      t.surface = true;
      break;
    case MapKind::roughness:
    case MapKind::metallic:
    case MapKind::opacity:
      t.channels = 1;
      t.png_format = PixelFormat::png8;
      t.surface = true;
      break;
  }
  return t;
}

TextureNeeds texture_needs(const std::vector<MapKind>& maps) {
  TextureNeeds needs;
  for (const MapKind m : maps) {
    needs.base_color = needs.base_color || m == MapKind::base_color;
    needs.roughness = needs.roughness || m == MapKind::roughness;
    needs.metallic = needs.metallic || m == MapKind::metallic;
    needs.emissive = needs.emissive || m == MapKind::emissive;
    needs.opacity = needs.opacity || m == MapKind::opacity;
  }
  return needs;
}

bool has_map_token(const std::string& path) { return path.find(kMapToken) != std::string::npos; }

std::string map_path(const std::string& path, MapKind map) {
  std::string out = path;
  const std::string token = kMapToken;
  for (std::size_t at = out.find(token); at != std::string::npos; at = out.find(token, at)) {
    out.replace(at, token.size(), to_string(map));
    at += std::string(to_string(map)).size();
  }
  return out;
}

PixelFormat map_format(MapKind map, PixelFormat format, bool format_given, const std::string& path) {
  if (format_given || format != PixelFormat::png16) return format;
  std::string extension = std::filesystem::path(path).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return extension == ".png" ? map_traits(map).png_format : format;
}

glm::vec3 part_color(const std::string& name) {
  std::uint32_t h = 2166136261u;
  for (const char c : name) {
    h ^= static_cast<unsigned char>(c);
    h *= 16777619u;
  }
  // A hue in [0, 6); HSV to RGB with s = 0.6, v = 0.9.
  const float hue = static_cast<float>(h >> 8) * 0x1p-24f * 6.0f;
  const float v = 0.9f, s = 0.6f;
  const int sector = std::min(5, static_cast<int>(hue));
  const float f = hue - static_cast<float>(sector);
  const float p = v * (1.0f - s), q = v * (1.0f - s * f), t = v * (1.0f - s * (1.0f - f));
  switch (sector) {
    case 0:
      return {v, t, p};
    case 1:
      return {q, v, p};
    case 2:
      return {p, v, t};
    case 3:
      return {p, q, v};
    case 4:
      return {t, p, v};
    default:
      return {v, p, q};
  }
}

IdSource resolve_id_source(IdSource requested, const Mesh& high) {
  if (requested != IdSource::automatic) return requested;
  return high.has_named_materials() ? IdSource::material : IdSource::part;
}

void MapMeshData::apply(MapSettings& settings) const {
  settings.position_bounds = position_bounds;
  settings.vertex_curvature = vertex_curvature.empty() ? nullptr : &vertex_curvature;
  settings.id_source = id_source;
  settings.triangle_id = id_colors.empty() ? nullptr : &triangle_id;
  settings.id_colors = id_colors.empty() ? nullptr : &id_colors;
  settings.transfer = transfer.triangle_material.empty() ? nullptr : &transfer;
}

namespace {

// The id map's colour of a material: its own colour (Kd, baseColorFactor),
// sRGB-encoded as the map's colours are display values, when the file gave
// one; else (and for parts) the hue of its name.
glm::vec3 material_id_color(const Mesh& high, IdSource source, const std::string& name) {
  if (source == IdSource::material) {
    if (const Material* m = high.material_def(name); m != nullptr && m->has_color) {
      return glm::vec3(linear_to_srgb(m->base_color.r), linear_to_srgb(m->base_color.g),
                       linear_to_srgb(m->base_color.b));
    }
  }
  return part_color(name);
}

// The vertex-color id source: each triangle's colour (the one most of its
// corners have, at 8 bits; the first corner's when all differ), the
// distinct colours in order of first use, named "#rrggbb".
void vertex_color_ids(const Mesh& high, std::vector<std::string>& names, std::vector<std::uint32_t>& id,
                      std::vector<glm::vec3>& colors) {
  NMBAKE_CHECK(high.has_colors(), "vertex colours loaded for a vertex-color id map");
  const auto key = [&](std::uint32_t v) {
    std::uint32_t k = 0;
    for (int c = 0; c < 3; ++c) {
      const float x = std::clamp(high.colors[v][c], 0.0f, 1.0f);
      k = k << 8 | static_cast<std::uint32_t>(std::lround(255.0f * x));
    }
    return k;
  };
  std::unordered_map<std::uint32_t, std::uint32_t> index;
  for (std::size_t t = 0; t < high.triangle_count(); ++t) {
    const std::uint32_t a = key(high.indices[3 * t]), b = key(high.indices[3 * t + 1]),
                        c = key(high.indices[3 * t + 2]);
    const std::uint32_t k = (b == c && a != b) ? b : a;
    auto [it, added] = index.emplace(k, static_cast<std::uint32_t>(colors.size()));
    if (added) {
      const glm::vec3 rgb(static_cast<float>(k >> 16) / 255.0f, static_cast<float>((k >> 8) & 255) / 255.0f,
                          static_cast<float>(k & 255) / 255.0f);
      colors.push_back(rgb);
      char name[8];
      std::snprintf(name, sizeof name, "#%06x", static_cast<unsigned>(k));
      names.emplace_back(name);
    }
    id[t] = it->second;
  }
  if (names.empty()) {
    names.emplace_back("#000000");
    colors.emplace_back(0.0f);
  }
}

// SurfaceTransfer's per-triangle data, in the scene's order.
void prepare_transfer(const Mesh& high, const BakeGroups& groups, SurfaceTransfer& out) {
  NMBAKE_CHECK(high.has_corner_uvs(), "corner UVs loaded for a transfer map");
  out.materials = high.material_defs;
  out.material_textures = out.textures.by_material;
  out.material_textures.resize(out.materials.size());
  out.materials.emplace_back();  // the default
  out.material_textures.emplace_back();
  const auto fallback = static_cast<std::uint32_t>(out.materials.size() - 1);
  std::vector<std::uint32_t> material(high.triangle_count(), fallback);
  for (const MeshPart& range : high.materials) {
    std::uint32_t index = fallback;
    for (std::size_t i = 0; i + 1 < out.materials.size(); ++i) {
      if (out.materials[i].name == range.name) index = static_cast<std::uint32_t>(i);
    }
    std::fill_n(material.begin() + range.first_triangle, range.triangle_count, index);
  }
  const auto density = [&](std::size_t t) {
    const std::uint32_t* c = &high.indices[3 * t];
    const glm::vec3 e1 = high.positions[c[1]] - high.positions[c[0]];
    const glm::vec3 e2 = high.positions[c[2]] - high.positions[c[0]];
    const glm::vec2 u1 = high.corner_uvs[3 * t + 1] - high.corner_uvs[3 * t];
    const glm::vec2 u2 = high.corner_uvs[3 * t + 2] - high.corner_uvs[3 * t];
    const float area = glm::length(glm::cross(e1, e2));
    const float uv_area = std::abs(u1.x * u2.y - u1.y * u2.x);
    const float d = area > 0.0f ? std::sqrt(uv_area / area) : 0.0f;
    return std::isfinite(d) ? d : 0.0f;
  };
  const auto add = [&](std::size_t t) {
    out.triangle_material.push_back(material[t]);
    for (int k = 0; k < 3; ++k) out.corner_uv.push_back(high.corner_uvs[3 * t + static_cast<std::size_t>(k)]);
    out.uv_density.push_back(density(t));
  };
  if (groups.grouped()) {
    for (const auto& triangles : groups.high_triangles) {
      for (const std::uint32_t t : triangles) add(t);
    }
  } else {
    for (std::size_t t = 0; t < high.triangle_count(); ++t) add(t);
  }
}

// The high's tangents (file order) into SurfaceTransfer, in the scene's order.
void prepare_normal_tangents(HighTangents tangents, const BakeGroups& groups, SurfaceTransfer& out) {
  out.tangent_stats = tangents.stats;
  out.tangent_seconds = tangents.seconds;
  if (!groups.grouped()) {
    out.corner_tangent = std::move(tangents.corner);
    return;
  }
  for (const auto& triangles : groups.high_triangles) {
    for (const std::uint32_t t : triangles) {
      for (std::size_t k = 0; k < 3; ++k)
        out.corner_tangent.push_back(tangents.corner[3 * std::size_t{t} + k]);
    }
  }
}

}  // namespace

HighTangents compute_high_tangents(const Mesh& high) {
  const auto begin = std::chrono::steady_clock::now();
  HighTangents out;
  std::vector<std::uint8_t> selected(high.triangle_count(), 0);
  bool any = false;
  for (const MeshPart& range : high.materials) {
    const Material* m = high.material_def(range.name);
    if (m == nullptr || m->normal_texture.empty() || range.triangle_count == 0) continue;
    std::fill_n(selected.begin() + range.first_triangle, range.triangle_count, std::uint8_t{1});
    any = true;
  }
  if (!any) return out;
  compute_corner_uv_tangents(high, selected, out.corner, out.stats);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();
  return out;
}

void prepare_map_mesh(const Mesh& high, const std::vector<MapKind>& maps, IdSource id_source,
                      const IdPalette& palette, const BakeGroups& groups, TextureSet textures,
                      MapMeshData& out, HighTangents high_tangents) {
  const auto wants = [&](MapKind map) { return std::find(maps.begin(), maps.end(), map) != maps.end(); };
  out = MapMeshData{};
  out.transfer.textures = std::move(textures);
  const bool normal_maps = !high_tangents.corner.empty();
  if (texture_needs(maps).any() || normal_maps) prepare_transfer(high, groups, out.transfer);
  if (normal_maps) prepare_normal_tangents(std::move(high_tangents), groups, out.transfer);
  if (wants(MapKind::position)) out.position_bounds = compute_bounds(high);
  if (wants(MapKind::curvature)) {
    if (high.has_normals()) {
      out.vertex_curvature = vertex_mean_curvature(high, high.normals, out.curvature);
    } else {
      Mesh shape;
      shape.positions = high.positions;
      shape.indices = high.indices;
      MeshStats shape_stats;
      compute_vertex_normals(shape, shape_stats);
      out.vertex_curvature = vertex_mean_curvature(shape, shape.normals, out.curvature);
    }
  }
  if (wants(MapKind::id)) {
    out.id_source = resolve_id_source(id_source, high);
    std::vector<std::string> names;
    std::vector<std::uint32_t> id(high.triangle_count(), 0);
    if (out.id_source == IdSource::vertex_color) {
      vertex_color_ids(high, names, id, out.id_colors);
    } else {
      const std::vector<MeshPart>& ranges = out.id_source == IdSource::material ? high.materials : high.parts;
      // One unnamed id when the file has none; a name in several ranges is
      // one id.
      for (const MeshPart& range : ranges) {
        const auto at = std::find(names.begin(), names.end(), range.name);
        const auto index = static_cast<std::uint32_t>(at - names.begin());
        if (at == names.end()) names.push_back(range.name);
        std::fill_n(id.begin() + range.first_triangle, range.triangle_count, index);
      }
      if (names.empty()) names.emplace_back();
      for (const std::string& name : names)
        out.id_colors.push_back(material_id_color(high, out.id_source, name));
      // A colour two names share would merge them in the mask (Blender
      // writes Kd 0.8 for every material it was not given one for): those
      // names take their hues. The palette's colours are the artist's
      // choice, shared or not.
      std::vector<bool> given(names.size()), shared(names.size());
      for (std::size_t i = 0; i < names.size(); ++i) {
        if (const glm::vec3* color = palette.find(names[i]); color != nullptr) {
          out.id_colors[i] = *color;
          given[i] = true;
        }
      }
      for (std::size_t i = 0; i < names.size(); ++i) {
        shared[i] = std::count(out.id_colors.begin(), out.id_colors.end(), out.id_colors[i]) > 1;
      }
      for (std::size_t i = 0; i < names.size(); ++i) {
        if (shared[i] && !given[i]) out.id_colors[i] = part_color(names[i]);
      }
    }
    for (std::size_t i = 0; i < names.size(); ++i) out.ids.emplace_back(names[i], out.id_colors[i]);
    if (groups.grouped()) {
      // The grouped index buffer holds each group's triangles in turn
      // (group_high_indices); a triangle in two groups is there twice.
      for (const auto& triangles : groups.high_triangles) {
        for (const std::uint32_t t : triangles) out.triangle_id.push_back(id[t]);
      }
    } else {
      out.triangle_id = std::move(id);
    }
  }
}

bool MapSettings::has(MapKind map) const { return std::find(maps.begin(), maps.end(), map) != maps.end(); }

double MapReport::figure(const std::string& name) const {
  for (const auto& f : figures) {
    if (f.first == name) return f.second;
  }
  return 0.0;
}

MapSet::MapSet(const MapSettings& settings, int width, int first_row, int last_row)
    : settings_(settings), first_row_(first_row), last_row_(last_row) {
  settings_.encode.out_row_begin = first_row;
  for (const MapKind map : settings_.maps) {
    std::unique_ptr<Module> m = make_map_module(map, settings_);
    m->image.width = width;
    m->image.height = last_row - first_row;
    m->image.channels = map_traits(map).channels;
    modules_.push_back(std::move(m));
  }
  // Every texel is written by its module, band by band; huge pages make
  // the first touch cheap (as the normal map's image before the map set).
  // The images side by side: sizing one zero-fills it on one core.
  tbb::parallel_for(std::size_t{0}, modules_.size(), [&](std::size_t i) {
    Image& image = modules_[i]->image;
    detail::size_output(image.pixels, static_cast<std::size_t>(image.width) * image.height * image.channels);
  });
}

MapSet::~MapSet() = default;

bool MapSet::needs_rays() const {
  return std::any_of(settings_.maps.begin(), settings_.maps.end(), [](MapKind m) {
    const MapTraits t = map_traits(m);
    return t.occlusion_rays || t.thickness_rays;
  });
}

void MapSet::trace_rays(const HighScene& scene, const Mesh& high, const LowSurface& surface,
                        const TexelSamples& samples, const Hits& hits) {
  const bool occlusion = settings_.has(MapKind::ao) || settings_.has(MapKind::bent_normal);
  if (occlusion) {
    OcclusionOptions options = settings_.occlusion;
    options.bent = settings_.has(MapKind::bent_normal);
    trace_occlusion(scene, high, surface, samples, hits, options, visibility_, bent_, occlusion_stats_);
  }
  if (settings_.has(MapKind::thickness)) {
    trace_thickness(scene, high, surface, samples, hits, settings_.thickness, thickness_, thickness_stats_);
  }
}

void MapSet::encode_band(const LowSurface& surface, const TexelSamples& samples, const Mesh& high,
                         const Hits& hits, EncodeStats& normal_stats) {
  NMBAKE_CHECK(samples.row_begin >= first_row_ && samples.row_begin + samples.height <= last_row_,
               "the band lies in the map set's rows");
  const BandInputs in{surface,      samples, high,        hits,
                      &visibility_, &bent_,  &thickness_, samples.row_begin - first_row_};
  HitValueImages values;
  std::vector<Module*> by_rows;
  for (const auto& m : modules_) {
    if (m->by_rows()) {
      by_rows.push_back(m.get());
      continue;
    }
    if (!m->from_hit_values()) {
      m->encode_band(in, settings_, normal_stats);
      continue;
    }
    switch (m->kind) {
      case MapKind::height:
        values.height = &m->image;
        break;
      case MapKind::position:
        values.position = &m->image;
        break;
      case MapKind::curvature:
        values.curvature = &m->image;
        break;
      default:
        values.miss = &m->image;
        break;
    }
  }
  const bool hit_values = values.height || values.position || values.curvature || values.miss;
  if (by_rows.empty() && !hit_values) return;
  // Blocks of about kBlockSamples samples (~0.5 MB of samples and hits):
  // after the normal map's pass over a block, the hit values' pass reads it
  // from cache. The moon's set, 2048^2 at 4 spp, alternating binaries:
  // encode 0.110 -> 0.101 s and 0.124 -> 0.111-0.115 s (blocks of 2 to 8
  // rows alike, 32 rows slower); the normal map alone the same.
  constexpr std::size_t kBlockSamples = 16384;
  const std::size_t row_samples = static_cast<std::size_t>(samples.width) * samples.samples;
  const int block_rows =
      static_cast<int>(std::max<std::size_t>(1, kBlockSamples / std::max<std::size_t>(1, row_samples)));
  const int blocks = (samples.height + block_rows - 1) / block_rows;
  std::vector<EncodeStats> stats(static_cast<std::size_t>(blocks) * by_rows.size());
  tbb::parallel_for(0, blocks, [&](int b) {
    const int row_begin = b * block_rows, row_end = std::min(samples.height, row_begin + block_rows);
    for (std::size_t i = 0; i < by_rows.size(); ++i) {
      by_rows[i]->encode_rows(in, settings_, row_begin, row_end, stats[b * by_rows.size() + i]);
    }
    if (hit_values) encode_hit_values(in, settings_, values, row_begin, row_end);
  });
  for (std::size_t i = 0; i < by_rows.size(); ++i) {
    EncodeStats band;
    for (int b = 0; b < blocks; ++b) band.add(stats[b * by_rows.size() + i]);
    by_rows[i]->rows_encoded(band, normal_stats);
  }
}

void MapSet::finish(std::vector<std::uint8_t>& coverage, int padding, DilateStats& dilate_stats) {
  for (const auto& m : modules_) m->finish(coverage);
  // Every map in one dilation: the rings are found once.
  std::vector<DilateLayer> layers;
  for (const auto& m : modules_) layers.push_back({&m->image, map_traits(m->kind).dilate});
  DilateStats s;
  dilate(layers, coverage, padding, s);
  dilate_stats.filled_texels += s.filled_texels;
  dilate_stats.fallback_texels += s.fallback_texels;
}

Image& MapSet::image(MapKind map) {
  for (const auto& m : modules_) {
    if (m->kind == map) return m->image;
  }
  NMBAKE_CHECK(false, "the map is in the set");
  return modules_.front()->image;
}

void MapSet::integer_mapping(MapKind map, float& scale, float& offset) const {
  for (const auto& m : modules_) {
    if (m->kind == map) return m->integer_mapping(scale, offset);
  }
  NMBAKE_CHECK(false, "the map is in the set");
}

std::vector<MapReport> MapSet::reports(int tile) const {
  std::vector<MapReport> out;
  for (const auto& m : modules_) {
    MapReport r;
    r.map = m->kind;
    r.tile = tile;
    r.figures = m->figures;
    const auto put = [&](const char* name, double value) { r.figures.emplace_back(name, value); };
    if (m->kind == MapKind::position) {
      // The box, for whoever turns the map back into positions, and its flat
      // axes (a plane: 0.5 stored on them), a counted fallback.
      const Bounds& box = settings_.position_bounds;
      const char* names[2][3] = {{"box_min_x", "box_min_y", "box_min_z"},
                                 {"box_max_x", "box_max_y", "box_max_z"}};
      for (int a = 0; a < 3; ++a) put(names[0][a], box.min[a]);
      for (int a = 0; a < 3; ++a) put(names[1][a], box.max[a]);
      int flat = 0;
      for (int a = 0; a < 3; ++a) flat += !(box.max[a] > box.min[a]);
      put("flat_axes", flat);
    }
    if (m->kind == MapKind::ao || m->kind == MapKind::bent_normal) {
      put("rays_per_sample", settings_.occlusion.rays);
      put("distance", settings_.occlusion.distance);
      put("samples", static_cast<double>(occlusion_stats_.samples));
      put("rays", static_cast<double>(occlusion_stats_.rays));
      put("unoccluded_rays", static_cast<double>(occlusion_stats_.unoccluded));
      put("mirrored_rays", static_cast<double>(occlusion_stats_.mirrored_rays));
      put("normal_fallbacks", static_cast<double>(occlusion_stats_.normal_fallbacks));
      put("untraced_rays", static_cast<double>(occlusion_stats_.untraced_rays));
      if (m->kind == MapKind::bent_normal)
        put("all_occluded_samples", static_cast<double>(occlusion_stats_.all_occluded));
    }
    if (m->kind == MapKind::id && settings_.id_colors != nullptr) {
      // From the bake's mesh data (a merge of tiles has none: not counters).
      put("ids", static_cast<double>(settings_.id_colors->size()));
      put("from_materials", settings_.id_source == IdSource::material ? 1.0 : 0.0);
    }
    if (m->kind == MapKind::thickness) {
      put("rays_per_sample", settings_.thickness.rays);
      put("distance", settings_.thickness.distance);
      put("samples", static_cast<double>(thickness_stats_.samples));
      put("rays", static_cast<double>(thickness_stats_.rays));
      put("exits", static_cast<double>(thickness_stats_.exits));
      put("samples_without_exit", static_cast<double>(thickness_stats_.samples_no_exit));
      put("normal_fallbacks", static_cast<double>(thickness_stats_.normal_fallbacks));
      put("untraced_rays", static_cast<double>(thickness_stats_.untraced_rays));
    }
    out.push_back(std::move(r));
  }
  return out;
}

MapCounts MapSet::counts() const {
  MapCounts c;
  for (const auto& m : modules_) c.maps.push_back(m->figures);
  c.occlusion = occlusion_stats_;
  c.thickness = thickness_stats_;
  return c;
}

void MapSet::add_counts(const MapCounts& c) {
  NMBAKE_CHECK(c.maps.size() == modules_.size(), "counts of a set of the same maps");
  for (std::size_t i = 0; i < modules_.size(); ++i) {
    for (const auto& [name, value] : c.maps[i]) modules_[i]->add(name.c_str(), value);
  }
  MapCounts from = c;
  const auto add = [](const auto& to, const auto& more) {
    for (std::size_t i = 0; i < to.size(); ++i) *to[i] += *more[i];
  };
  add(counters(occlusion_stats_), counters(from.occlusion));
  add(counters(thickness_stats_), counters(from.thickness));
}

}  // namespace nmbake
