// glTF 2.0 through load_mesh() (tinygltf and our accessor checks, the same
// entry `nmbake bake --low x.glb` uses). The first byte picks .gltf (JSON,
// data: URIs) or .glb, its next bits ask for vertex colours (COLOR_0),
// tangents, and materials with corner UVs (as a texture bake loads the
// high mesh; the embedded images, buffer views and data: URIs, are then
// decoded as the bake would: a hostile header must be refused, not
// allocated); the rest is the file. Seeds: tests/fuzz/corpus/gltf/
// and, at run time, the small glTF models of assimp-testmodels (tools/fuzz).
//
// Byte mutations rarely keep a JSON document valid, so most of them only
// reach nlohmann's parser. The custom mutator below mutates the structure
// instead, half of the time: a .gltf's JSON is parsed and one field changed
// the way a broken exporter or a hostile file would (indices negative or
// past 2^31, counts, offsets, strides and lengths off by one or huge,
// component types, zero or projective matrices, uris that name folders or
// leave the folder); a .glb's header and chunk fields (magic, version,
// lengths, chunk types) are set to edge values. Anything else, and every
// input that does not parse, goes to libFuzzer's own mutator.
#include <algorithm>
#include <cstring>
#include <iterator>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "fuzz_util.hpp"
#include "nmbake/textures.hpp"

extern "C" std::size_t LLVMFuzzerMutate(std::uint8_t* data, std::size_t size, std::size_t max_size);

namespace {

using json = nlohmann::json;
using Random = std::minstd_rand;

std::size_t pick(Random& random, std::size_t n) { return n == 0 ? 0 : random() % n; }

// Every value of the document with the key it is under ("" in an array),
// depth first; deep nesting is cut, since a hostile seed may nest without end.
void collect(json& value, const std::string& key, int depth,
             std::vector<std::pair<json*, std::string>>& out) {
  out.emplace_back(&value, key);
  if (depth > 24) return;
  if (value.is_object()) {
    for (auto it = value.begin(); it != value.end(); ++it) collect(it.value(), it.key(), depth + 1, out);
  } else if (value.is_array()) {
    for (json& element : value) collect(element, key, depth + 1, out);
  }
}

json edge_integer(Random& random, const json& old) {
  const std::int64_t value = old.is_number_integer() ? old.get<std::int64_t>() : 0;
  switch (pick(random, 12)) {
    case 0:
      return -1;
    case 1:
      return std::numeric_limits<std::int32_t>::min();
    case 2:
      return std::uint64_t{1} << 31;
    case 3:
      return (std::uint64_t{1} << 32) + 1;
    case 4:
      return std::uint64_t{1} << 40;
    case 5:
      return std::numeric_limits<std::uint64_t>::max();
    case 6:
      return value + 1;
    case 7:
      return value - 1;
    case 8:
      return value * 2 + 1;
    case 9:
      return 0;
    case 10:
      return 0.5;
    default:
      return static_cast<std::int64_t>(pick(random, 8));
  }
}

json edge_matrix(Random& random) {
  json m = json::array({1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1});
  switch (pick(random, 6)) {
    case 0:
      return json::array({0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0});
    case 1:
      m[11] = 0.5;
      return m;  // projective
    case 2:
      m[0] = 1e308;
      m[5] = 1e308;
      return m;
    case 3:
      m[0] = 0;
      m[5] = 0;
      m[10] = 0;
      return m;  // singular, affine
    case 4:
      m.erase(15);
      return m;  // 15 numbers
    default:
      m[0] = -1;
      return m;  // mirror
  }
}

json edge_uri(Random& random) {
  static const char* const kUris[] = {".",
                                      "..",
                                      "/",
                                      "../../etc/passwd",
                                      "/etc/passwd",
                                      "/dev/zero",
                                      "",
                                      "%2e%2e/x.bin",
                                      "sub/../../x.bin",
                                      "input.gltf",
                                      "./input.glb",
                                      "data:application/octet-stream;base64,AAAA",
                                      "data:application/octet-stream;base64,!!!!",
                                      "data:,",
                                      "x.bin%00y"};
  return std::string(kUris[pick(random, std::size(kUris))]);
}

bool mutate_json(json& doc, Random& random) {
  std::vector<std::pair<json*, std::string>> values;
  collect(doc, "", 0, values);
  if (values.size() < 2) return false;
  auto& [value, key] = values[1 + pick(random, values.size() - 1)];
  if (key == "componentType") {
    static const int kTypes[] = {5120, 5121, 5122, 5123, 5125, 5126, 5130, 0, -5126};
    *value = kTypes[pick(random, std::size(kTypes))];
  } else if (key == "matrix") {
    *value = edge_matrix(random);
  } else if (key == "uri") {
    *value = edge_uri(random);
  } else if (key == "rotation" || key == "scale" || key == "translation") {
    *value = pick(random, 2) ? json::array({0, 0, 0, 0}) : json::array({1e308, -1e308, 0});
  } else if (key == "version") {
    *value = pick(random, 2) ? "1.0" : "3.0";
  } else if (value->is_number()) {
    *value = edge_integer(random, *value);
  } else if (value->is_array() && !value->empty()) {
    // Drop an element, or repeat one (a node listed twice, a cycle).
    if (pick(random, 2))
      value->erase(pick(random, value->size()));
    else
      value->push_back((*value)[pick(random, value->size())]);
  } else if (value->is_object() && !value->empty()) {
    auto it = value->begin();
    std::advance(it, static_cast<std::ptrdiff_t>(pick(random, value->size())));
    value->erase(it);
  } else {
    *value = edge_integer(random, *value);
  }
  return true;
}

std::uint32_t edge_u32(Random& random, std::uint32_t old, std::size_t file_size) {
  const auto size = static_cast<std::uint32_t>(file_size);
  const std::uint32_t values[] = {
      0, 1, 2, 3, 4, 12, 20, 0x7fffffffu, 0xffffffffu, size, size - 4, size + 4, old + 4, old - 4, old + 1};
  return values[pick(random, std::size(values))];
}

// A .glb: one header or chunk field set to an edge value, or its JSON chunk
// mutated as above (the chunk's length rewritten to match).
std::size_t mutate_glb(std::uint8_t* file, std::size_t size, std::size_t max_size, Random& random) {
  if (size < 20) return 0;
  std::uint32_t json_length;
  std::memcpy(&json_length, file + 12, 4);
  if (pick(random, 2) == 0 && json_length <= size - 20) {
    json doc = json::parse(file + 20, file + 20 + json_length, nullptr, false);
    if (!doc.is_discarded() && mutate_json(doc, random)) {
      std::string text = doc.dump();
      while (text.size() % 4 != 0) text += ' ';
      const std::size_t rest = size - 20 - json_length;
      if (20 + text.size() + rest > max_size) return 0;
      std::vector<std::uint8_t> out(file, file + 20);
      out.insert(out.end(), text.begin(), text.end());
      out.insert(out.end(), file + 20 + json_length, file + size);
      const auto new_length = static_cast<std::uint32_t>(text.size());
      const auto total = static_cast<std::uint32_t>(out.size());
      std::memcpy(out.data() + 12, &new_length, 4);
      std::memcpy(out.data() + 8, &total, 4);
      std::memcpy(file, out.data(), out.size());
      return out.size();
    }
  }
  // Offsets of the magic, version, total length, JSON chunk length and type,
  // and, when it is inside the file, the BIN chunk's length and type.
  std::vector<std::size_t> fields = {0, 4, 8, 12, 16};
  if (size >= 28 && json_length <= size - 28) {
    fields.push_back(20 + json_length);
    fields.push_back(24 + json_length);
  }
  const std::size_t at = fields[pick(random, fields.size())];
  std::uint32_t old;
  std::memcpy(&old, file + at, 4);
  const std::uint32_t value =
      at == 0 ? (pick(random, 2) ? 0x46546c67u /* "glTF" */ : 0x4e4f534au) : edge_u32(random, old, size);
  std::memcpy(file + at, &value, 4);
  return size;
}

}  // namespace

extern "C" std::size_t LLVMFuzzerCustomMutator(std::uint8_t* data, std::size_t size, std::size_t max_size,
                                               unsigned int seed) {
  Random random(seed);
  if (size >= 2 && pick(random, 2) == 0) {
    std::size_t done = 0;
    if (data[0] % 2 == 1) {
      done = mutate_glb(data + 1, size - 1, max_size - 1, random);
    } else {
      json doc = json::parse(data + 1, data + size, nullptr, false);
      if (!doc.is_discarded() && mutate_json(doc, random)) {
        const std::string text = doc.dump();
        if (text.size() + 1 <= max_size) {
          std::memcpy(data + 1, text.data(), text.size());
          done = text.size();
        }
      }
    }
    if (done > 0) return done + 1;
  }
  return LLVMFuzzerMutate(data, size, max_size);
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const nmbake::fuzz::InputFile file(data + 1, size - 1, data[0] % 2 ? "input.glb" : "input.gltf");
  nmbake::Mesh mesh;
  nmbake::LoadStats stats;
  nmbake::LoadOptions options;
  options.keep_colors = (data[0] & 2) != 0;
  options.keep_tangents = (data[0] & 4) != 0;
  options.material_defs = options.corner_uvs = (data[0] & 8) != 0;
  const nmbake::Status status = nmbake::load_mesh(file.path(), options, mesh, stats);
  // What the loader returns holds together (one colour and tangent a vertex).
  if (status.is_ok() && !nmbake::validate_mesh(mesh, file.path())) __builtin_trap();
  if (status.is_ok()) (void)nmbake::check_coordinate_range(mesh, file.path());
  if (status.is_ok() && !mesh.embedded_images.empty()) {
    nmbake::TextureNeeds needs;
    needs.base_color = needs.roughness = needs.metallic = needs.emissive = needs.opacity = true;
    nmbake::TextureSet textures;
    if (nmbake::load_material_textures(mesh, file.path(), needs, textures).code() ==
        nmbake::StatusCode::internal) {
      std::abort();
    }
  }
  return 0;
}
