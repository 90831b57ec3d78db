// `nmbake view`: the review .glb (the low mesh as baked, wearing its maps)
// and the self-contained page around it (review.hpp). The high mesh, when
// given, is simplified for the page by vertex clustering (Rossignac and
// Borrel, "Multi-resolution 3D approximations for rendering complex
// scenes", 1993): positions snapped to a uniform grid, one vertex per
// occupied cell (the mean of its positions and of its normals), triangles
// whose corners fall in fewer than three cells dropped.
#include "nmbake/review.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <glm/geometric.hpp>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <unordered_map>

#include "image/png.hpp"
#include "inspect/preview_draw.hpp"
#include "inspect/review_template.hpp"
#include "nmbake/image.hpp"
#include "nmbake/load.hpp"
#include "nmbake/maps.hpp"
#include "nmbake/tangents.hpp"
#include "nmbake/udim.hpp"

namespace nmbake {

namespace {

std::string base64(const void* data, std::size_t size) {
  static constexpr char kDigits[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  const auto* p = static_cast<const unsigned char*>(data);
  std::string out;
  out.reserve((size + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < size; i += 3) {
    const std::uint32_t v = (std::uint32_t{p[i]} << 16) | (std::uint32_t{p[i + 1]} << 8) | p[i + 2];
    out += kDigits[v >> 18];
    out += kDigits[(v >> 12) & 63];
    out += kDigits[(v >> 6) & 63];
    out += kDigits[v & 63];
  }
  if (i < size) {
    const std::uint32_t v = (std::uint32_t{p[i]} << 16) | (i + 1 < size ? std::uint32_t{p[i + 1]} << 8 : 0u);
    out += kDigits[v >> 18];
    out += kDigits[(v >> 12) & 63];
    out += i + 1 < size ? kDigits[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

Status read_text_file(const std::string& path, std::string& out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::bad_input(path + ": cannot open");
  std::ostringstream s;
  s << in.rdbuf();
  if (!in.good() && !in.eof()) return Status::bad_input(path + ": cannot read");
  out = std::move(s).str();
  return Status::ok();
}

bool stretched_kind(const std::string& kind) {
  return kind == "height" || kind == "curvature" || kind == "thickness";
}

// Where the map goes in the .glb's material (empty: the page's own list).
std::string material_slot(const std::string& kind) {
  if (kind == "normal") return "normal";
  if (kind == "ao") return "occlusion";
  if (kind == "base-color") return "base_color";
  if (kind == "emissive") return "emissive";
  return "";
}

// The high mesh within `budget` triangles: vertex clustering on a grid of
// `cells` per side of the bounding cube, halved until it fits.
void simplify_high(const Mesh& high, std::uint64_t budget, std::vector<float>& positions,
                   std::vector<float>& normals, std::vector<std::uint32_t>& indices) {
  positions.clear();
  normals.clear();
  indices.clear();
  if (high.triangle_count() <= budget) {
    for (std::size_t v = 0; v < high.vertex_count(); ++v) {
      for (int c = 0; c < 3; ++c) {
        positions.push_back(high.positions[v][c]);
        normals.push_back(high.normals[v][c]);
      }
    }
    indices.assign(high.indices.begin(), high.indices.end());
    return;
  }
  const Bounds bounds = compute_bounds(high);
  const glm::vec3 extent = bounds.max - bounds.min;
  const float side = std::max({extent.x, extent.y, extent.z, 1e-12f});
  for (int cells = 1024; cells >= 2; cells /= 2) {
    const float scale = static_cast<float>(cells) / side;
    std::unordered_map<std::uint64_t, std::uint32_t> cell_vertex;
    std::vector<std::uint32_t> vertex_of(high.vertex_count());
    std::vector<glm::dvec3> sum_position, sum_normal;
    std::vector<std::uint32_t> count;
    for (std::size_t v = 0; v < high.vertex_count(); ++v) {
      const glm::vec3 q = (high.positions[v] - bounds.min) * scale;
      const auto cell = [&](float x) {
        return static_cast<std::uint64_t>(std::clamp(static_cast<int>(x), 0, cells - 1));
      };
      const std::uint64_t key = (cell(q.x) << 42) | (cell(q.y) << 21) | cell(q.z);
      const auto [it, added] = cell_vertex.emplace(key, static_cast<std::uint32_t>(sum_position.size()));
      if (added) {
        sum_position.emplace_back(0.0);
        sum_normal.emplace_back(0.0);
        count.push_back(0);
      }
      vertex_of[v] = it->second;
      sum_position[it->second] += glm::dvec3(high.positions[v]);
      sum_normal[it->second] += glm::dvec3(high.normals[v]);
      ++count[it->second];
    }
    std::vector<std::uint32_t> kept;
    for (std::size_t t = 0; t < high.triangle_count(); ++t) {
      const std::uint32_t a = vertex_of[high.indices[3 * t]], b = vertex_of[high.indices[3 * t + 1]],
                          c = vertex_of[high.indices[3 * t + 2]];
      if (a == b || b == c || a == c) continue;
      kept.insert(kept.end(), {a, b, c});
    }
    if (kept.size() / 3 > budget && cells > 2) continue;
    for (std::size_t v = 0; v < sum_position.size(); ++v) {
      const glm::dvec3 p = sum_position[v] / static_cast<double>(count[v]);
      glm::dvec3 n = sum_normal[v];
      const double l = glm::length(n);
      n = l > 1e-12 ? n / l : glm::dvec3(0.0, 0.0, 1.0);
      for (int c = 0; c < 3; ++c) {
        positions.push_back(static_cast<float>(p[c]));
        normals.push_back(static_cast<float>(n[c]));
      }
    }
    indices = std::move(kept);
    return;
  }
}

// `text` safe inside a <script> element (no "</" closes it early).
std::string script_safe(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '<' && i + 1 < text.size() && text[i + 1] == '/') {
      out += "<\\/";
      ++i;
    } else {
      out += text[i];
    }
  }
  return out;
}

// The template with each token replaced by its value, tokens searched in
// the template only (never in a value already put in).
std::string fill_template(const std::string& text,
                          const std::vector<std::pair<std::string, std::string>>& values) {
  std::string out;
  std::size_t from = 0;
  for (;;) {
    std::size_t best = std::string::npos;
    const std::pair<std::string, std::string>* which = nullptr;
    for (const auto& v : values) {
      const std::size_t at = text.find(v.first, from);
      if (at < best) {
        best = at;
        which = &v;
      }
    }
    if (which == nullptr) break;
    out.append(text, from, best - from);
    out += which->second;
    from = best + which->first.size();
  }
  out.append(text, from, std::string::npos);
  return out;
}

// glTF's metallicRoughnessTexture of each tile from the roughness and
// metallic maps (the first of each kind given): G roughness (1 without a
// roughness map, as glTF's factor), B metallic (0 without), R unused (1).
// The maps stay in the page's own list too.
Status pack_metallic_roughness(const std::vector<ReviewMap>& maps,
                               std::map<int, GltfMaterialTextures>& materials) {
  const ReviewMap* roughness = nullptr;
  const ReviewMap* metallic = nullptr;
  for (const ReviewMap& m : maps) {
    if (m.kind == "roughness" && roughness == nullptr) roughness = &m;
    if (m.kind == "metallic" && metallic == nullptr) metallic = &m;
  }
  if (roughness == nullptr && metallic == nullptr) return Status::ok();
  for (auto& [tile, material] : materials) {
    Image r, m;
    if (roughness != nullptr) NMBAKE_TRY(read_image(udim_path(roughness->path, tile), r));
    if (metallic != nullptr) NMBAKE_TRY(read_image(udim_path(metallic->path, tile), m));
    if (roughness != nullptr && metallic != nullptr && (r.width != m.width || r.height != m.height)) {
      return Status::bad_input(udim_path(metallic->path, tile) + ": " + std::to_string(m.width) + "x" +
                               std::to_string(m.height) + ", but the roughness map " +
                               udim_path(roughness->path, tile) + " is " + std::to_string(r.width) + "x" +
                               std::to_string(r.height) + ": glTF packs them in one texture");
    }
    Image packed;
    packed.width = roughness != nullptr ? r.width : m.width;
    packed.height = roughness != nullptr ? r.height : m.height;
    packed.channels = 3;
    packed.pixels.resize(static_cast<std::size_t>(packed.width) * packed.height * 3);
    for (int y = 0; y < packed.height; ++y) {
      for (int x = 0; x < packed.width; ++x) {
        float* p = packed.at(x, y);
        p[0] = 1.0f;
        p[1] = roughness != nullptr ? r.at(x, y)[0] : 1.0f;
        p[2] = metallic != nullptr ? m.at(x, y)[0] : 0.0f;
      }
    }
    const std::vector<std::uint8_t> bytes = image_detail::encode_png(packed, 8, /*dither=*/false);
    material.metallic_roughness_png.assign(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  }
  return Status::ok();
}

}  // namespace

const char* review_map_kinds() {
  return "normal, ao, height, curvature, thickness, bent-normal, object-normal, position, vertex-color, id, "
         "miss, base-color, roughness, metallic, emissive, opacity";
}

bool review_map_kind_known(const std::string& kind) {
  MapKind k;
  return parse_word(kind, k);
}

Status review_map_png(const std::string& kind, const std::string& path, std::string& png, float range[2]) {
  Image image;
  NMBAKE_TRY(read_image(path, image));
  range[0] = 0.0f;
  range[1] = 1.0f;
  float scale = 1.0f, offset = 0.0f;
  if (stretched_kind(kind) && !image.pixels.empty()) {
    float lo = image.pixels[0], hi = image.pixels[0];
    for (std::size_t i = 0; i < image.pixels.size(); i += static_cast<std::size_t>(image.channels)) {
      if (!std::isfinite(image.pixels[i])) continue;
      lo = std::min(lo, image.pixels[i]);
      hi = std::max(hi, image.pixels[i]);
    }
    range[0] = lo;
    range[1] = hi;
    if (hi > lo) {
      scale = 1.0f / (hi - lo);
      offset = -lo * scale;
    }
  }
  // Rounded, not dithered: the page shows the map's values as they are.
  const std::vector<std::uint8_t> bytes = image_detail::encode_png(image, 8, /*dither=*/false, scale, offset);
  png.assign(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  return Status::ok();
}

Status build_review(const ReviewOptions& options, std::string& glb, std::string& html, ReviewStats& stats) {
  stats = ReviewStats{};
  // three.js first: a missing package is found before any work.
  const std::filesystem::path three(options.three_dir);
  std::string three_js, loader_js, controls_js;
  const std::string three_files[3] = {(three / "three.min.js").string(),
                                      (three / "examples/js/loaders/GLTFLoader.js").string(),
                                      (three / "examples/js/controls/OrbitControls.js").string()};
  std::string* three_texts[3] = {&three_js, &loader_js, &controls_js};
  for (int i = 0; i < 3; ++i) {
    if (!read_text_file(three_files[i], *three_texts[i])) {
      return Status::bad_input(
          three_files[i] +
          ": three.js is missing (the page inlines it; Debian: apt-get install libjs-three)");
    }
  }
  if (options.maps.empty()) return Status::bad_input("nothing to review: give at least one --map");

  // The low mesh as the bake prepares it, its MikkTSpace tangents and tiles.
  Mesh low, high;
  LowSurface surface;
  NMBAKE_TRY(load_preview_meshes(options.low, options.high, low, surface, high));
  std::vector<glm::vec4> corner_tangents;
  TangentStats tangent_stats;
  compute_tangents(low, corner_tangents, tangent_stats);
  stats.fallback_tangents = tangent_stats.fallback_tangents;
  bool udim = false;
  for (const ReviewMap& m : options.maps) udim = udim || has_udim_token(m.path);
  NMBAKE_TRY(find_udim_tiles(low, options.low, udim, stats.tiles));
  std::vector<int> triangle_tile(low.triangle_count(), 1001);
  for (std::size_t t = 0; t < low.triangle_count(); ++t) {
    // As find_udim_tiles() places it: the tile of the UV centroid.
    const glm::vec2 c =
        (low.uvs[low.indices[3 * t]] + low.uvs[low.indices[3 * t + 1]] + low.uvs[low.indices[3 * t + 2]]) /
        3.0f;
    triangle_tile[t] = 1001 + static_cast<int>(std::floor(static_cast<double>(c.x))) +
                       10 * static_cast<int>(std::floor(static_cast<double>(c.y)));
  }
  const Mesh review = vertex_tangent_mesh(low, corner_tangents, triangle_tile);
  stats.low_triangles = review.triangle_count();
  stats.low_vertices = review.vertex_count();

  // The maps: the glTF's material slots, the rest for the page.
  nlohmann::json maps = nlohmann::json::array();
  std::map<int, GltfMaterialTextures> materials;
  for (const int tile : stats.tiles) materials[tile].name = "tile_" + std::to_string(tile);
  for (std::size_t i = 0; i < options.maps.size(); ++i) {
    const ReviewMap& m = options.maps[i];
    if (!review_map_kind_known(m.kind)) {
      return Status::bad_input(m.path + ": unknown map kind '" + m.kind + "' (known: " + review_map_kinds() +
                               ")");
    }
    const std::string slot = material_slot(m.kind);
    nlohmann::json entry{{"kind", m.kind},
                         {"file", std::filesystem::path(m.path).filename().string()},
                         {"slot", slot},
                         {"tiles", nlohmann::json::object()}};
    for (const int tile : stats.tiles) {
      const std::string path = udim_path(m.path, tile);
      std::string png;
      float range[2];
      NMBAKE_TRY(review_map_png(m.kind, path, png, range));
      nlohmann::json t{{"range", {range[0], range[1]}}};
      GltfMaterialTextures& material = materials[tile];
      std::string* target = slot == "normal"       ? &material.normal_png
                            : slot == "occlusion"  ? &material.occlusion_png
                            : slot == "base_color" ? &material.base_color_png
                            : slot == "emissive"   ? &material.emissive_png
                                                   : nullptr;
      if (target != nullptr && target->empty()) {
        *target = std::move(png);
      } else {
        entry["slot"] = "";
        t["png"] = base64(png.data(), png.size());
      }
      entry["tiles"][std::to_string(tile)] = std::move(t);
    }
    maps.push_back(std::move(entry));
  }
  NMBAKE_TRY(pack_metallic_roughness(options.maps, materials));
  std::vector<GltfMaterialTextures> material_list;
  for (auto& [tile, material] : materials) material_list.push_back(std::move(material));
  NMBAKE_TRY(encode_textured_glb(review, material_list, glb));
  stats.glb_bytes = glb.size();

  nlohmann::json config;
  config["low"] = std::filesystem::path(options.low).filename().string();
  config["maps"] = std::move(maps);
  config["tiles"] = stats.tiles;
  // The preview's framing: the bounding sphere of the low and the high.
  const preview_detail::Framing framing =
      options.high.empty() ? preview_detail::frame_points({&surface.position})
                           : preview_detail::frame_points({&surface.position, &high.positions});
  config["framing"] = {{"centre", {framing.centre.x, framing.centre.y, framing.centre.z}},
                       {"radius", framing.radius}};
  config["view"] = {{"size", options.view.size},
                    {"yaw", options.view.yaw_degrees},
                    {"pitch", options.view.pitch_degrees},
                    {"up", options.view.up == UpAxis::y ? "y" : "z"},
                    {"light", {options.view.light.x, options.view.light.y, options.view.light.z}}};
  config["background"] = {preview_detail::kBackground.x, preview_detail::kBackground.y,
                          preview_detail::kBackground.z};
  config["served"] = options.served;
  config["high"] = nullptr;
  if (!options.high.empty()) {
    std::vector<float> positions, normals;
    std::vector<std::uint32_t> indices;
    simplify_high(high, options.high_budget, positions, normals, indices);
    stats.high_triangles = high.triangle_count();
    stats.high_triangles_shown = indices.size() / 3;
    config["high"] = {{"file", std::filesystem::path(options.high).filename().string()},
                      {"triangles", stats.high_triangles},
                      {"shown", stats.high_triangles_shown},
                      {"positions", base64(positions.data(), positions.size() * sizeof(float))},
                      {"normals", base64(normals.data(), normals.size() * sizeof(float))},
                      {"indices", base64(indices.data(), indices.size() * sizeof(std::uint32_t))}};
  }
  config["report"] = nullptr;
  if (!options.report.empty()) {
    std::string text;
    NMBAKE_TRY(read_text_file(options.report, text));
    nlohmann::json report = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
    if (report.is_discarded() || !report.is_object())
      return Status::bad_input(options.report + ": not a JSON object (expected a bake report)");
    config["report"] = std::move(report);
  }

  const std::string scripts = three_js + "\n" + loader_js + "\n" + controls_js;
  if (scripts.find("</script") != std::string::npos)
    return Status::bad_input(options.three_dir + ": three.js contains \"</script\": cannot be inlined");
  html = fill_template(review_detail::kViewerHtml, {{"/*NMBAKE_THREE*/", scripts},
                                                    {"/*NMBAKE_VIEWER*/", review_detail::kViewerJs},
                                                    {"NMBAKE_CONFIG", script_safe(config.dump())},
                                                    {"NMBAKE_GLB", base64(glb.data(), glb.size())}});
  stats.html_bytes = html.size();
  return Status::ok();
}

}  // namespace nmbake
