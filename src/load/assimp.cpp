// FBX (binary and ASCII), Collada, 3DS and STL through Assimp 5.2
// (Debian's libassimp-dev).
//
// Assimp only parses: the node tree is walked here, each node's meshes get
// the node's world matrix, and polygons are fan-triangulated from corner 0
// here too, exactly like the OBJ loader. Assimp's own aiProcess_Triangulate
// would split a convex quad along 0-2 as well, but starts a concave quad at
// its reflex corner and ear-clips larger polygons, so the same asset would
// get other triangles (and other MikkTSpace tangents) as FBX than as OBJ.
//
// Assimp's post-processing is limited to RemoveComponent (what the bake does
// not keep is dropped) and ValidateDataStructure (inconsistent files become
// errors). Vertices are welded here by the kept attributes only (weld()), so
// a high mesh is not split at UV seams.
// Assimp's default logger is a null logger and is never replaced, so it
// prints nothing; its error string goes into the Status.
//
// Materials: each aiMesh has one (FBX and Collada meshes are split by
// material on import), named by AI_MATKEY_NAME; the names Assimp invents
// for meshes without one (AI_DEFAULT_MATERIAL_NAME "DefaultMaterial", the
// 3DS importer's "%%%DEFAULT") read as "" (no material).
// Material definitions (LoadOptions::material_defs), for every material a
// mesh uses, from the aiMaterial: base colour AI_MATKEY_BASE_COLOR (PBR
// materials), else AI_MATKEY_COLOR_DIFFUSE (has_color when either is there);
// AI_MATKEY_OPACITY into its alpha; AI_MATKEY_COLOR_EMISSIVE;
// AI_MATKEY_ROUGHNESS_FACTOR and AI_MATKEY_METALLIC_FACTOR; the first
// texture of BASE_COLOR (else DIFFUSE), EMISSIVE, OPACITY (its alpha, or its
// luminance without one, as MTL's map_d), NORMALS, DIFFUSE_ROUGHNESS and
// METALNESS (their luminance), with their wrap modes (Decal, "nothing
// outside", reads as clamp). A texture replaces its factor, as for MTL
// (Blender's FBX exporter writes a diffuse colour of 0.8 beside the image
// it connects; Blender's importer shows the image alone). A texture on a UV
// channel other than 0 is refused when a bake needs it (only set 0 is
// read: Mesh::corner_uvs). Texture paths follow the MTL rule (mtl.cpp): a
// path that exists is read as given (FBX stores absolute paths from the
// artist's machine; any DCC opening the file reads them too), else relative
// to the mesh file's folder, else its file name in that folder; a path
// naming one of Assimp's embedded textures ("*N", or the file name of one,
// aiScene::GetEmbeddedTextureAndIndex) is that image, copied into
// Mesh::embedded_images (compressed as stored; Assimp's raw BGRA texels as
// RGBA).
// Corner UVs (LoadOptions::corner_uvs): UV channel uv_set of every triangle
// corner, (0, 0) and counted on meshes without it.
// Vertex colours (keep_colors): aiMesh::mColors[0] as Assimp hands them
// over, which is as the file stores them: neither the FBX nor the Collada
// importer converts a colour space (FBX LayerElementColor and Collada COLOR
// hold the display values modellers paint, as a PLY's bytes: sRGB-encoded,
// nmbake's convention); white on meshes without colours.
#include <assimp/config.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <assimp/version.h>

#include <algorithm>
#include <array>
#include <assimp/Importer.hpp>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <glm/gtc/matrix_inverse.hpp>
#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "load/isolated.hpp"
#include "load/parsers.hpp"

namespace nmbake::load_detail {

bool is_assimp_extension(const std::string& extension) {
  // Formats whose Assimp importers keep names and node transforms and that
  // texture artists export meshes in; .blend (Assimp reads only 2.7x files)
  // and .obj/.ply/.gltf (our own loaders) are not among them.
  return extension == ".fbx" || extension == ".dae" || extension == ".3ds" || extension == ".stl";
}

namespace {

glm::dmat4 to_glm(const aiMatrix4x4& m) {
  // Assimp's matrices are row-major (a1..a4 the first row); glm's columns.
  glm::dmat4 out;
  const std::array<std::array<ai_real, 4>, 4> rows{{{m.a1, m.a2, m.a3, m.a4},
                                                    {m.b1, m.b2, m.b3, m.b4},
                                                    {m.c1, m.c2, m.c3, m.c4},
                                                    {m.d1, m.d2, m.d3, m.d4}}};
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) out[c][r] = rows[static_cast<std::size_t>(r)][static_cast<std::size_t>(c)];
  }
  return out;
}

// FBX's UnitScaleFactor is the length of a file unit in centimetres; Assimp
// keeps it in the scene metadata (as float or double depending on the file).
double unit_meters(const aiScene& scene) {
  if (scene.mMetaData == nullptr) return 0.0;
  float f = 0.0f;
  double d = 0.0;
  if (scene.mMetaData->Get("UnitScaleFactor", f) && f > 0.0f) return 0.01 * f;
  if (scene.mMetaData->Get("UnitScaleFactor", d) && d > 0.0) return 0.01 * d;
  return 0.0;
}

// The weld that aiProcess_JoinIdenticalVertices would do, done here: FBX
// stores attributes per polygon corner, so Assimp hands over one vertex per
// corner (24M for an 8M-triangle mesh); its own pass took 8.8 of 10.4 s and
// 3 GB on that mesh (BENCHMARKS.md). Vertices are equal when every kept
// attribute is bitwise equal; an open-addressing hash table keeps the first
// of each, in vertex order. Returns the new index of every vertex and puts
// the old index of each new vertex into `representatives`.
std::vector<std::uint32_t> weld(const aiMesh& mesh, bool normals, const aiVector3D* uv, bool tangents,
                                const aiColor4D* colors, std::vector<std::uint32_t>& representatives) {
  const unsigned n = mesh.mNumVertices;
  const auto key = [&](unsigned v, float* k) {
    int size = 0;
    const auto put = [&](const aiVector3D& a, int components) {
      k[size++] = a.x;
      k[size++] = a.y;
      if (components == 3) k[size++] = a.z;
    };
    put(mesh.mVertices[v], 3);
    if (normals) put(mesh.mNormals[v], 3);
    if (uv != nullptr) put(uv[v], 2);
    if (tangents) {
      put(mesh.mTangents[v], 3);
      put(mesh.mBitangents[v], 3);
    }
    if (colors != nullptr) {
      k[size++] = colors[v].r;
      k[size++] = colors[v].g;
      k[size++] = colors[v].b;
      k[size++] = colors[v].a;
    }
    return size;
  };
  std::size_t capacity = 16;
  while (capacity < 2 * std::size_t{n}) capacity *= 2;
  constexpr std::uint32_t kEmpty = 0xffffffffu;
  std::vector<std::uint32_t> slots(capacity, kEmpty);  // new vertex index
  std::vector<std::uint32_t> remap(n);
  representatives.clear();
  float k[18];
  float other[18];
  for (unsigned v = 0; v < n; ++v) {
    const int size = key(v, k);
    std::uint64_t h = 0x9e3779b97f4a7c15ull;
    for (int i = 0; i < size; ++i) {
      std::uint32_t bits;
      std::memcpy(&bits, &k[i], 4);
      h = (h ^ bits) * 0xff51afd7ed558ccdull;
      h ^= h >> 29;
    }
    for (std::size_t slot = h & (capacity - 1);; slot = (slot + 1) & (capacity - 1)) {
      if (slots[slot] == kEmpty) {
        slots[slot] = static_cast<std::uint32_t>(representatives.size());
        remap[v] = slots[slot];
        representatives.push_back(v);
        break;
      }
      key(representatives[slots[slot]], other);
      if (std::memcmp(k, other, static_cast<std::size_t>(size) * sizeof(float)) == 0) {
        remap[v] = slots[slot];
        break;
      }
    }
  }
  return remap;
}

class AssimpReader {
 public:
  AssimpReader(const std::string& path, const aiScene& scene, const LoadOptions& options, Mesh& out,
               LoadStats& stats)
      : path_(path), scene_(scene), options_(options), out_(out), stats_(stats) {}

  Status read() {
    if (scene_.mRootNode == nullptr) return Status::bad_input(path_ + ": Assimp: the file has no node tree");
    // Depth first with an explicit stack; the children keep their order.
    struct Entry {
      const aiNode* node;
      glm::dmat4 parent;
    };
    std::vector<Entry> stack{{scene_.mRootNode, glm::dmat4(1.0)}};
    std::size_t node_number = 0;
    while (!stack.empty()) {
      const Entry entry = stack.back();
      stack.pop_back();
      const glm::dmat4 world = entry.parent * to_glm(entry.node->mTransformation);
      if (entry.node->mNumMeshes > 0) NMBAKE_TRY(read_node(*entry.node, node_number, world));
      ++node_number;
      for (unsigned c = entry.node->mNumChildren; c-- > 0;) {
        if (entry.node->mChildren[c] != nullptr) stack.push_back({entry.node->mChildren[c], world});
      }
    }
    if (out_.indices.empty())
      return Status::bad_input(path_ + ": no triangles (points and lines are skipped)");
    if (!all_normals_) out_.normals.clear();
    if (!all_uvs_) out_.uvs.clear();
    if (!all_tangents_) out_.tangents.clear();
    // White where a mesh had no colours, none at all when no mesh had them.
    if (!any_colors_) out_.colors.clear();
    if (options_.material_defs) read_material_defs();
    stats_.triangles = out_.triangle_count();
    return Status::ok();
  }

 private:
  // ------------------------------------------------------------ materials

  // Mesh::material_defs for every material a mesh used (see the top of the file).
  void read_material_defs() {
    for (const unsigned index : used_materials_) {
      const aiMaterial& source = *scene_.mMaterials[index];
      Material def;
      def.name = material_name(index);
      if (def.name.empty() || out_.material_def(def.name) != nullptr) continue;
      aiColor4D color4;
      aiColor3D color3;
      if (source.Get(AI_MATKEY_BASE_COLOR, color4) == AI_SUCCESS) {
        def.base_color = glm::vec4(color4.r, color4.g, color4.b, 1.0f);
        def.has_color = true;
      } else if (source.Get(AI_MATKEY_COLOR_DIFFUSE, color3) == AI_SUCCESS) {
        def.base_color = glm::vec4(color3.r, color3.g, color3.b, 1.0f);
        def.has_color = true;
      }
      ai_real value = 0;
      if (source.Get(AI_MATKEY_OPACITY, value) == AI_SUCCESS) def.base_color.a = static_cast<float>(value);
      if (source.Get(AI_MATKEY_COLOR_EMISSIVE, color3) == AI_SUCCESS) {
        def.emissive = glm::vec3(color3.r, color3.g, color3.b);
      }
      if (source.Get(AI_MATKEY_ROUGHNESS_FACTOR, value) == AI_SUCCESS)
        def.roughness = static_cast<float>(value);
      if (source.Get(AI_MATKEY_METALLIC_FACTOR, value) == AI_SUCCESS)
        def.metallic = static_cast<float>(value);
      const bool finite = std::isfinite(def.base_color.r) && std::isfinite(def.base_color.g) &&
                          std::isfinite(def.base_color.b) && std::isfinite(def.base_color.a) &&
                          std::isfinite(def.roughness) && std::isfinite(def.metallic) &&
                          std::isfinite(def.emissive.r) && std::isfinite(def.emissive.g) &&
                          std::isfinite(def.emissive.b);
      if (!finite) {
        const bool has_color = def.has_color;
        def = Material{};
        def.name = material_name(index);
        def.has_color = has_color;
      }
      def.base_color_texture =
          texture_ref(source, source.GetTextureCount(aiTextureType_BASE_COLOR) > 0 ? aiTextureType_BASE_COLOR
                                                                                   : aiTextureType_DIFFUSE);
      def.emissive_texture = texture_ref(source, aiTextureType_EMISSIVE);
      def.opacity_texture = texture_ref(source, aiTextureType_OPACITY);
      def.opacity_texture.channel = 3;  // alpha, or the luminance of an image without one
      def.normal_texture = texture_ref(source, aiTextureType_NORMALS);
      def.roughness_texture = texture_ref(source, aiTextureType_DIFFUSE_ROUGHNESS);
      def.metallic_texture = texture_ref(source, aiTextureType_METALNESS);
      // A texture replaces its factor (see the top of the file).
      if (!def.base_color_texture.empty()) def.base_color = glm::vec4(1.0f, 1.0f, 1.0f, def.base_color.a);
      if (!def.opacity_texture.empty()) def.base_color.a = 1.0f;
      if (!def.emissive_texture.empty()) def.emissive = glm::vec3(1.0f);
      if (!def.roughness_texture.empty()) def.roughness = 1.0f;
      if (!def.metallic_texture.empty()) def.metallic = 1.0f;
      out_.material_defs.push_back(std::move(def));
    }
  }

  // The first texture of `type`, or an empty ref.
  TextureRef texture_ref(const aiMaterial& source, aiTextureType type) {
    TextureRef ref;
    aiString file;
    unsigned uv_index = 0;
    std::array<aiTextureMapMode, 3> modes{aiTextureMapMode_Wrap, aiTextureMapMode_Wrap,
                                          aiTextureMapMode_Wrap};
    if (source.GetTextureCount(type) == 0 ||
        source.GetTexture(type, 0, &file, nullptr, &uv_index, nullptr, nullptr, modes.data()) != AI_SUCCESS) {
      return ref;
    }
    const auto wrap = [](aiTextureMapMode mode) {
      return mode == aiTextureMapMode_Clamp || mode == aiTextureMapMode_Decal ? TextureWrap::clamp
             : mode == aiTextureMapMode_Mirror                                ? TextureWrap::mirror
                                                                              : TextureWrap::repeat;
    };
    ref.wrap_u = wrap(modes[0]);
    ref.wrap_v = wrap(modes[1]);
    ref.texcoord = static_cast<int>(uv_index);
    const std::string name(file.C_Str(), file.length);
    if (name.empty()) {
      ref.problem = "the texture has an empty path";
      return ref;
    }
    if (name.find('\0') != std::string::npos) {
      ref.problem = "the texture path holds a NUL byte";
      return ref;
    }
    if (uv_index != 0) {
      ref.problem = "the texture reads UV channel " + std::to_string(uv_index) + "; only channel 0 is read";
      return ref;
    }
    const auto [texture, texture_index] = scene_.GetEmbeddedTextureAndIndex(name.c_str());
    if (texture != nullptr) {
      ref.embedded = embedded_image(*texture, static_cast<unsigned>(texture_index));
      if (ref.embedded < 0) {
        ref.problem = "embedded image " + std::to_string(texture_index) + " is larger than " +
                      std::to_string(kMaxEmbeddedSide) + " pixels a side";
      }
      return ref;
    }
    if (name.front() == '*') {
      ref.problem = "embedded image " + printable_text(name.substr(1)) + " does not exist (the file holds " +
                    std::to_string(scene_.mNumTextures) + ")";
      return ref;
    }
    ref.path = resolve_texture_path(name);
    return ref;
  }

  // The MTL rule (mtl.cpp): as given if it exists, else beside the mesh
  // file, else its file name beside the mesh file.
  std::string resolve_texture_path(std::string name) const {
    namespace fs = std::filesystem;
    if (name.rfind("file://", 0) == 0) name.erase(0, 7);
    std::replace(name.begin(), name.end(), '\\', '/');
    const fs::path folder = fs::path(path_).parent_path();
    const fs::path given(name);
    const fs::path beside = given.is_absolute() ? given : folder / given;
    std::error_code ec;
    if (fs::exists(beside, ec) || name.find("<UDIM>") != std::string::npos) return beside.string();
    const fs::path by_name = folder / given.filename();
    if (given.has_parent_path() && fs::exists(by_name, ec)) return by_name.string();
    return beside.string();  // missing: the bake that needs it says so
  }

  // Assimp's texture `index` as Mesh::embedded_images[result], copied once;
  // -1 for raw texels larger than a texture may be.
  static constexpr unsigned kMaxEmbeddedSide = 65536;
  int embedded_image(const aiTexture& texture, unsigned index) {
    if (const auto it = embedded_.find(index); it != embedded_.end()) return it->second;
    EmbeddedImage image;
    if (texture.mHeight == 0) {
      image.format = std::string(texture.achFormatHint, strnlen(texture.achFormatHint, HINTMAXTEXTURELEN));
      const auto* bytes = reinterpret_cast<const unsigned char*>(texture.pcData);
      if (bytes != nullptr) image.bytes.assign(bytes, bytes + texture.mWidth);
    } else {
      if (texture.mWidth > kMaxEmbeddedSide || texture.mHeight > kMaxEmbeddedSide) return -1;
      image.width = static_cast<int>(texture.mWidth);
      image.height = static_cast<int>(texture.mHeight);
      const std::size_t texels = std::size_t{texture.mWidth} * texture.mHeight;
      image.bytes.resize(texels * 4);
      for (std::size_t t = 0; t < texels && texture.pcData != nullptr; ++t) {
        const aiTexel& texel = texture.pcData[t];
        image.bytes[4 * t + 0] = texel.r;
        image.bytes[4 * t + 1] = texel.g;
        image.bytes[4 * t + 2] = texel.b;
        image.bytes[4 * t + 3] = texel.a;
      }
    }
    const int result = static_cast<int>(out_.embedded_images.size());
    out_.embedded_images.push_back(std::move(image));
    embedded_.emplace(index, result);
    return result;
  }

  Status error(const std::string& part, const std::string& reason) const {
    return Status::bad_input(path_ + ": part '" + part + "': " + reason);
  }

  Status read_node(const aiNode& node, std::size_t node_number, const glm::dmat4& world) {
    const std::string name =
        node.mName.length > 0 ? std::string(node.mName.C_Str()) : "node" + std::to_string(node_number);
    if (!part_names_.insert(name).second) {
      return Status::bad_input(path_ + ": two parts are named '" + name + "': part names must be unique");
    }
    const glm::dmat3 linear(world);
    const double det = glm::determinant(linear);
    const bool mirrored = det < 0.0;
    const glm::dmat3 normal_matrix = det != 0.0 ? glm::inverseTranspose(linear) : glm::dmat3(0.0);
    const std::size_t first_triangle = out_.triangle_count();
    for (unsigned m = 0; m < node.mNumMeshes; ++m) {
      if (node.mMeshes[m] >= scene_.mNumMeshes || scene_.mMeshes[node.mMeshes[m]] == nullptr) {
        return error(name, "mesh " + std::to_string(node.mMeshes[m]) + " does not exist");
      }
      const aiMesh& mesh = *scene_.mMeshes[node.mMeshes[m]];
      const std::size_t mesh_first = out_.triangle_count();
      NMBAKE_TRY(read_mesh(name, mesh, world, normal_matrix, mirrored));
      append_range(out_.materials, material_name(mesh), static_cast<std::uint32_t>(mesh_first),
                   static_cast<std::uint32_t>(out_.triangle_count() - mesh_first));
    }
    const std::size_t triangle_count = out_.triangle_count() - first_triangle;
    if (triangle_count > 0) {
      out_.parts.push_back(MeshPart{name, static_cast<std::uint32_t>(first_triangle),
                                    static_cast<std::uint32_t>(triangle_count)});
    }
    return Status::ok();
  }

  // The mesh's material name; "" for none and for the names Assimp invents.
  std::string material_name(const aiMesh& mesh) {
    if (mesh.mMaterialIndex >= scene_.mNumMaterials || scene_.mMaterials[mesh.mMaterialIndex] == nullptr)
      return {};
    if (std::find(used_materials_.begin(), used_materials_.end(), mesh.mMaterialIndex) ==
        used_materials_.end())
      used_materials_.push_back(mesh.mMaterialIndex);
    return material_name(mesh.mMaterialIndex);
  }
  std::string material_name(unsigned index) const {
    aiString name;
    if (scene_.mMaterials[index]->Get(AI_MATKEY_NAME, name) != AI_SUCCESS) return {};
    const std::string text(name.C_Str(), name.length);
    return text == AI_DEFAULT_MATERIAL_NAME || text == "%%%DEFAULT" ? std::string() : text;
  }

  Status read_mesh(const std::string& part, const aiMesh& mesh, const glm::dmat4& world,
                   const glm::dmat3& normal_matrix, bool mirrored) {
    const std::string where = "mesh '" + std::string(mesh.mName.C_Str()) + "': ";
    // Points and lines first: a mesh of only those adds no vertices.
    std::uint64_t polygons = 0;
    for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
      if (mesh.mFaces[f].mNumIndices < 3) {
        ++stats_.degenerate_faces;
      } else {
        ++polygons;
      }
    }
    if (polygons == 0) return Status::ok();
    stats_.polygons += polygons;

    const bool normals = options_.keep_normals && mesh.mNormals != nullptr;
    all_normals_ = all_normals_ && normals;
    if (options_.keep_uvs) {
      const auto set = static_cast<unsigned>(options_.uv_set);
      const bool has_set = set < AI_MAX_NUMBER_OF_TEXTURECOORDS && mesh.mTextureCoords[set] != nullptr;
      if (!has_set) {
        std::string sets;
        for (unsigned s = 0; s < AI_MAX_NUMBER_OF_TEXTURECOORDS; ++s) {
          if (mesh.mTextureCoords[s] != nullptr) sets += (sets.empty() ? "" : ", ") + std::to_string(s);
        }
        // No UVs anywhere with set 0 asked for: a mesh to unwrap, like an
        // OBJ without vt. Anything else is a missing set.
        if (options_.uv_set != 0 || !sets.empty() || any_uvs_) {
          return error(part, where + "UV channel " + std::to_string(options_.uv_set) +
                                 " is missing; the mesh has UV channels: " + (sets.empty() ? "none" : sets));
        }
        all_uvs_ = false;
      } else {
        if (!all_uvs_)
          return error(part,
                       where + "has UV channel " + std::to_string(set) + " but an earlier mesh has no UVs");
        any_uvs_ = true;
      }
    } else {
      all_uvs_ = false;
    }
    if (options_.keep_tangents) {
      // All meshes of the file have tangents, or none: a part without them
      // could not be baked with --tangents file.
      const bool has = mesh.mTangents != nullptr && mesh.mBitangents != nullptr && mesh.mNormals != nullptr;
      if (tangents_seen_ && has != all_tangents_) {
        return error(part, where + (has ? "has tangents but an earlier mesh has none"
                                        : "has no tangents but an earlier mesh has"));
      }
      tangents_seen_ = true;
      all_tangents_ = has;
    } else {
      all_tangents_ = false;
    }

    // One vertex per distinct combination of the kept attributes.
    const aiVector3D* uv = all_uvs_ ? mesh.mTextureCoords[options_.uv_set] : nullptr;
    const aiColor4D* colors = options_.keep_colors ? mesh.mColors[0] : nullptr;
    std::vector<std::uint32_t> representatives;
    const std::vector<std::uint32_t> remap =
        weld(mesh, all_normals_, uv, all_tangents_, colors, representatives);
    if (out_.positions.size() + representatives.size() > 0xffffffffu)
      return error(part, where + "more than 2^32 vertices in the file");
    const auto base = static_cast<std::uint32_t>(out_.positions.size());
    for (const std::uint32_t v : representatives) {
      const aiVector3D& p = mesh.mVertices[v];
      out_.positions.emplace_back(glm::vec3(world * glm::dvec4(p.x, p.y, p.z, 1.0)));
    }
    if (all_normals_) {
      for (const std::uint32_t v : representatives) {
        const aiVector3D& n = mesh.mNormals[v];
        out_.normals.emplace_back(glm::vec3(normal_matrix * glm::dvec3(n.x, n.y, n.z)));
      }
    } else {
      out_.normals.clear();
    }
    if (all_uvs_) {
      // Assimp, like FBX and nmbake, puts v = 0 at the bottom of the image.
      for (const std::uint32_t v : representatives) out_.uvs.emplace_back(uv[v].x, uv[v].y);
    }
    if (all_tangents_) {
      const glm::dmat3 linear(world);
      for (const std::uint32_t v : representatives) {
        const aiVector3D& t = mesh.mTangents[v];
        const aiVector3D& b = mesh.mBitangents[v];
        const aiVector3D& n = mesh.mNormals[v];
        // The sign of the frame as the file has it: + when (T, B, N) is
        // right-handed (B = cross(N, T) in MikkTSpace terms); a mirroring
        // node matrix flips it, as for glTF.
        const double handedness = (n ^ t) * b;
        float w = handedness < 0.0 ? -1.0f : 1.0f;
        if (mirrored) w = -w;
        out_.tangents.emplace_back(glm::vec3(linear * glm::dvec3(t.x, t.y, t.z)), w);
      }
    } else {
      out_.tangents.clear();
    }
    if (options_.keep_colors) {
      // As stored (see the top of the file); white without colours.
      any_colors_ = any_colors_ || colors != nullptr;
      for (const std::uint32_t v : representatives) {
        out_.colors.push_back(colors != nullptr
                                  ? glm::vec4(colors[v].r, colors[v].g, colors[v].b, colors[v].a)
                                  : glm::vec4(1.0f));
      }
    }

    // Corner UVs: the UV set of every corner, v = 0 at the bottom as above.
    const auto corner_set = static_cast<unsigned>(options_.uv_set);
    const aiVector3D* corner_uv = options_.corner_uvs && corner_set < AI_MAX_NUMBER_OF_TEXTURECOORDS
                                      ? mesh.mTextureCoords[corner_set]
                                      : nullptr;
    for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
      const aiFace& face = mesh.mFaces[f];
      if (face.mNumIndices < 3) continue;
      for (unsigned c = 0; c < face.mNumIndices; ++c) {
        if (face.mIndices[c] >= mesh.mNumVertices) {
          return error(part, where + "face " + std::to_string(f) + " index " +
                                 std::to_string(face.mIndices[c]) + " is out of range (" +
                                 std::to_string(mesh.mNumVertices) + " vertices)");
        }
      }
      // A fan from corner 0, like the OBJ loader (see the top of the file).
      for (unsigned c = 1; c + 1 < face.mNumIndices; ++c) {
        std::uint32_t b = face.mIndices[c];
        std::uint32_t d = face.mIndices[c + 1];
        if (mirrored) std::swap(b, d);  // keep counter-clockwise the front
        out_.indices.push_back(base + remap[face.mIndices[0]]);
        out_.indices.push_back(base + remap[b]);
        out_.indices.push_back(base + remap[d]);
        if (options_.corner_uvs) {
          for (const std::uint32_t v : {face.mIndices[0], b, d}) {
            if (corner_uv == nullptr) ++stats_.corners_without_uvs;
            out_.corner_uvs.push_back(corner_uv == nullptr ? glm::vec2(0.0f)
                                                           : glm::vec2(corner_uv[v].x, corner_uv[v].y));
          }
        }
      }
    }
    return Status::ok();
  }

  const std::string& path_;
  const aiScene& scene_;
  const LoadOptions& options_;
  Mesh& out_;
  LoadStats& stats_;
  std::set<std::string> part_names_;
  bool all_normals_ = true;
  bool all_uvs_ = true;
  bool any_uvs_ = false;
  bool all_tangents_ = true;
  bool tangents_seen_ = false;
  bool any_colors_ = false;
  std::vector<unsigned> used_materials_;  // scene material indices, in order of first use
  std::map<unsigned, int> embedded_;      // Assimp texture index -> Mesh::embedded_images
};

// Reads in this process; `read_done` is called when Assimp has returned.
Status load_assimp_here(const std::string& path, const LoadOptions& options, Mesh& out, LoadStats& stats,
                        const std::function<void()>& read_done) {
  {
    // Assimp's message for a missing file is vague; ours names the reason.
    FileReader probe;
    NMBAKE_TRY(probe.open(path));
    stats.bytes = probe.file_size();
  }
  Assimp::Importer importer;
  // Pivots folded into each node's matrix, so a model is one node that
  // carries its own name (not "$AssimpFbx$" helper nodes around it).
  importer.SetPropertyBool(AI_CONFIG_IMPORT_FBX_PRESERVE_PIVOTS, false);
  // What the bake does not keep is not even copied out of Assimp's scene.
  int removed = aiComponent_BONEWEIGHTS | aiComponent_ANIMATIONS | aiComponent_LIGHTS | aiComponent_CAMERAS;
  if (!options.material_defs) removed |= aiComponent_TEXTURES;  // the embedded images
  if (!options.keep_colors) removed |= aiComponent_COLORS;
  if (!options.keep_uvs && !options.corner_uvs) removed |= aiComponent_TEXCOORDS;
  if (!options.keep_normals) removed |= aiComponent_NORMALS;
  if (!options.keep_tangents) removed |= aiComponent_TANGENTS_AND_BITANGENTS;
  importer.SetPropertyInteger(AI_CONFIG_PP_RVC_FLAGS, removed);
  const aiScene* scene = importer.ReadFile(path, aiProcess_RemoveComponent | aiProcess_ValidateDataStructure);
  read_done();
  if (scene == nullptr) {
    std::string reason = importer.GetErrorString();
    // Assimp sizes arrays from counts in the file and reports the failed
    // allocation of a count no file of this size can hold as std::bad_alloc
    // (a 10 KB 3DS claiming a 103 GB vertex array; found by fuzz_assimp).
    if (reason.find("bad_alloc") != std::string::npos) {
      reason =
          "a count in the file asks for more memory than there is (std::bad_alloc): a broken or truncated "
          "file";
    }
    while (!reason.empty() && (reason.back() == '\n' || reason.back() == '\r')) reason.pop_back();
    return Status::bad_input(path +
                             ": Assimp: " + (reason.empty() ? std::string("cannot read the file") : reason));
  }
  if ((scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE) != 0) {
    return Status::bad_input(path + ": Assimp: the scene is incomplete (no meshes could be read)");
  }
  stats.unit_meters = lower_extension(path) == ".fbx" ? unit_meters(*scene) : 0.0;
  AssimpReader reader(path, *scene, options, out, stats);
  return reader.read();
}

}  // namespace

// Assimp reads in a process of its own (load/isolated.hpp): it crashes on
// some broken files and allocates what their counts say.
Status load_assimp(const std::string& path, const LoadOptions& options, Mesh& out, LoadStats& stats) {
  if (!options.isolate_libraries) return load_assimp_here(path, options, out, stats, [] {});
  return load_in_child(
      path, "Assimp",
      [&](Mesh& mesh, LoadStats& child_stats, const std::function<void()>& read_done) {
        return load_assimp_here(path, options, mesh, child_stats, read_done);
      },
      out, stats);
}

}  // namespace nmbake::load_detail

namespace nmbake {

std::string assimp_version() {
  return std::to_string(aiGetVersionMajor()) + "." + std::to_string(aiGetVersionMinor()) + "." +
         std::to_string(aiGetVersionPatch());
}

}  // namespace nmbake
