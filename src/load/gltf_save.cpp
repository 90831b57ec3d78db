// glTF 2.0 writer (tinygltf): positions, normals, UVs (TEXCOORD_0), tangents
// (TANGENT), vertex colours (COLOR_0, linear) and indices of a Mesh as .glb, or as .gltf JSON with its buffer
// for a .bin beside it; a node per part, a primitive per material range
// within it (materials carry only their names, or, for encode_textured_glb(),
// PBR textures embedded as PNG images); save_mesh() writes each to a
// temporary name and renames it.
#include <algorithm>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "load/parsers.hpp"
#include "load/tinygltf.hpp"
#include "nmbake/color.hpp"

namespace nmbake::load_detail {

namespace {

// Appends `bytes` to the buffer as a new, 4-byte aligned buffer view and
// returns its index.
int add_view(tinygltf::Model& model, const void* bytes, std::size_t size, int target) {
  std::vector<unsigned char>& data = model.buffers[0].data;
  while (data.size() % 4 != 0) data.push_back(0);
  tinygltf::BufferView view;
  view.buffer = 0;
  view.byteOffset = data.size();
  view.byteLength = size;
  view.target = target;
  const auto* first = static_cast<const unsigned char*>(bytes);
  data.insert(data.end(), first, first + size);
  model.bufferViews.push_back(view);
  return static_cast<int>(model.bufferViews.size()) - 1;
}

int add_accessor(tinygltf::Model& model, int view, int component_type, int type, std::size_t count) {
  tinygltf::Accessor accessor;
  accessor.bufferView = view;
  accessor.byteOffset = 0;
  accessor.componentType = component_type;
  accessor.type = type;
  accessor.count = count;
  model.accessors.push_back(accessor);
  return static_cast<int>(model.accessors.size()) - 1;
}

// The material's textures as glTF images in the buffer (image/png), each
// with its texture on the one shared sampler.
void add_textures(tinygltf::Model& model, const GltfMaterialTextures& textures,
                  tinygltf::Material& material) {
  if (model.samplers.empty()) {
    // Bilinear and clamped, as the baker's preview samples the map; mipmaps
    // for minification.
    tinygltf::Sampler sampler;
    sampler.magFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
    sampler.minFilter = TINYGLTF_TEXTURE_FILTER_LINEAR_MIPMAP_LINEAR;
    sampler.wrapS = TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE;
    sampler.wrapT = TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE;
    model.samplers.push_back(sampler);
  }
  const auto texture = [&](const std::string& png, const char* what) {
    if (png.empty()) return -1;
    tinygltf::Image image;
    image.name = material.name + "_" + what;
    image.mimeType = "image/png";
    image.bufferView = add_view(model, png.data(), png.size(), 0);
    model.images.push_back(image);
    tinygltf::Texture t;
    t.sampler = 0;
    t.source = static_cast<int>(model.images.size()) - 1;
    model.textures.push_back(t);
    return static_cast<int>(model.textures.size()) - 1;
  };
  material.normalTexture.index = texture(textures.normal_png, "normal");
  material.occlusionTexture.index = texture(textures.occlusion_png, "occlusion");
  material.pbrMetallicRoughness.baseColorTexture.index = texture(textures.base_color_png, "base_color");
  material.pbrMetallicRoughness.metallicRoughnessTexture.index =
      texture(textures.metallic_roughness_png, "metallic_roughness");
  material.emissiveTexture.index = texture(textures.emissive_png, "emissive");
  if (!textures.emissive_png.empty()) material.emissiveFactor = {1.0, 1.0, 1.0};
  // Without a metallic-roughness map: a dielectric, moderately rough, so
  // the normal map reads in any glTF viewer.
  if (textures.metallic_roughness_png.empty()) {
    material.pbrMetallicRoughness.metallicFactor = 0.0;
    material.pbrMetallicRoughness.roughnessFactor = 0.6;
  }
}

}  // namespace

Status encode_gltf(const Mesh& mesh, const std::string& bin_uri, std::string& bytes, std::string& bin_bytes,
                   const std::vector<GltfMaterialTextures>* textures) {
  const bool binary = bin_uri.empty();
  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "nmbake";
  model.buffers.emplace_back();

  const std::size_t vertex_count = mesh.vertex_count();
  const int position_view =
      add_view(model, mesh.positions.data(), vertex_count * sizeof(glm::vec3), TINYGLTF_TARGET_ARRAY_BUFFER);
  const int position =
      add_accessor(model, position_view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, vertex_count);
  // The specification requires POSITION's bounds.
  const Bounds bounds = compute_bounds(mesh);
  model.accessors[static_cast<std::size_t>(position)].minValues = {bounds.min.x, bounds.min.y, bounds.min.z};
  model.accessors[static_cast<std::size_t>(position)].maxValues = {bounds.max.x, bounds.max.y, bounds.max.z};
  std::map<std::string, int> attributes{{"POSITION", position}};
  if (mesh.has_normals()) {
    const int view =
        add_view(model, mesh.normals.data(), vertex_count * sizeof(glm::vec3), TINYGLTF_TARGET_ARRAY_BUFFER);
    attributes["NORMAL"] =
        add_accessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, vertex_count);
  }
  if (mesh.has_uvs()) {
    // Back to glTF's top-left UV origin (the loader's v' = 1 - v, undone).
    std::vector<glm::vec2> flipped(mesh.uvs);
    for (glm::vec2& uv : flipped) uv.y = 1.0f - uv.y;
    const int view =
        add_view(model, flipped.data(), vertex_count * sizeof(glm::vec2), TINYGLTF_TARGET_ARRAY_BUFFER);
    attributes["TEXCOORD_0"] =
        add_accessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC2, vertex_count);
  }
  if (mesh.has_tangents()) {
    const int view =
        add_view(model, mesh.tangents.data(), vertex_count * sizeof(glm::vec4), TINYGLTF_TARGET_ARRAY_BUFFER);
    attributes["TANGENT"] =
        add_accessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC4, vertex_count);
  }
  std::vector<glm::vec4> linear_colors;  // must live until the buffer is encoded
  if (mesh.has_colors()) {
    // glTF colours are linear; nmbake's are sRGB-encoded (load.hpp): the
    // loader's curve, inverted.
    const auto decode = srgb_to_linear;
    linear_colors.reserve(vertex_count);
    for (const glm::vec4& c : mesh.colors)
      linear_colors.emplace_back(decode(c.r), decode(c.g), decode(c.b), c.a);
    const int view =
        add_view(model, linear_colors.data(), vertex_count * sizeof(glm::vec4), TINYGLTF_TARGET_ARRAY_BUFFER);
    attributes["COLOR_0"] =
        add_accessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC4, vertex_count);
  }
  const int index_view = add_view(model, mesh.indices.data(), mesh.indices.size() * sizeof(std::uint32_t),
                                  TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);

  // One node per part (a mesh without parts is one unnamed node), each
  // drawing its range of the shared index buffer, so a reload gives back the
  // same parts with the same names; within a part one primitive per
  // material range, with a material of that name (none for ""), so the
  // materials come back too.
  const auto whole = [&](const std::vector<MeshPart>& ranges) {
    return ranges.empty()
               ? std::vector<MeshPart>{MeshPart{"", 0, static_cast<std::uint32_t>(mesh.triangle_count())}}
               : ranges;
  };
  const std::vector<MeshPart> parts = whole(mesh.parts);
  const std::vector<MeshPart> materials = whole(mesh.materials);
  std::map<std::string, int> material_index;
  for (const MeshPart& range : materials) {
    if (range.name.empty() || material_index.count(range.name) != 0) continue;
    tinygltf::Material material;
    material.name = range.name;
    if (textures != nullptr) {
      for (const GltfMaterialTextures& t : *textures) {
        if (t.name == range.name) add_textures(model, t, material);
      }
    }
    model.materials.push_back(material);
    material_index[range.name] = static_cast<int>(model.materials.size()) - 1;
  }
  tinygltf::Scene scene;
  std::size_t next_material = 0;  // the material range holding the part's first triangle
  for (const MeshPart& part : parts) {
    tinygltf::Mesh gltf_mesh;
    gltf_mesh.name = part.name;
    const std::uint32_t part_end = part.first_triangle + part.triangle_count;
    for (std::uint32_t first = part.first_triangle; first < part_end;) {
      while (materials[next_material].first_triangle + materials[next_material].triangle_count <= first)
        ++next_material;
      const MeshPart& material = materials[next_material];
      const std::uint32_t end = std::min(part_end, material.first_triangle + material.triangle_count);
      const int indices = add_accessor(model, index_view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                       TINYGLTF_TYPE_SCALAR, std::size_t{end - first} * 3);
      model.accessors[static_cast<std::size_t>(indices)].byteOffset =
          std::size_t{first} * 3 * sizeof(std::uint32_t);
      tinygltf::Primitive primitive;
      primitive.attributes = attributes;
      primitive.indices = indices;
      primitive.mode = TINYGLTF_MODE_TRIANGLES;
      primitive.material = material.name.empty() ? -1 : material_index[material.name];
      gltf_mesh.primitives.push_back(primitive);
      first = end;
    }
    model.meshes.push_back(gltf_mesh);
    tinygltf::Node node;
    node.name = part.name;
    node.mesh = static_cast<int>(model.meshes.size()) - 1;
    model.nodes.push_back(node);
    scene.nodes.push_back(static_cast<int>(model.nodes.size()) - 1);
  }
  model.scenes.push_back(scene);
  model.defaultScene = 0;
  model.buffers[0].data.resize((model.buffers[0].data.size() + 3) / 4 * 4, 0);

  std::vector<unsigned char> buffer;
  if (!binary) {
    // tinygltf's stream writer embeds buffers as base64; the data is taken
    // out here and the buffer's uri and length set in the JSON after.
    buffer.swap(model.buffers[0].data);
  }
  std::ostringstream stream;
  tinygltf::TinyGLTF writer;
  if (!writer.WriteGltfSceneToStream(&model, stream, /*prettyPrint=*/!binary, binary)) {
    return Status::internal("glTF writer failed");
  }
  bytes = std::move(stream).str();
  if (!binary) {
    nlohmann::json doc = nlohmann::json::parse(bytes, nullptr, /*allow_exceptions=*/false);
    if (doc.is_discarded() || !doc.contains("buffers"))
      return Status::internal("glTF writer: unexpected JSON");
    doc["buffers"][0]["uri"] = bin_uri;
    doc["buffers"][0]["byteLength"] = buffer.size();
    bytes = doc.dump(2);
    bin_bytes.assign(reinterpret_cast<const char*>(buffer.data()), buffer.size());
  }
  return Status::ok();
}

}  // namespace nmbake::load_detail

namespace nmbake {

Status encode_textured_glb(const Mesh& mesh, const std::vector<GltfMaterialTextures>& materials,
                           std::string& glb) {
  NMBAKE_TRY(validate_mesh(mesh, "review glTF"));
  std::string unused;
  return load_detail::encode_gltf(mesh, "", glb, unused, &materials);
}

}  // namespace nmbake
