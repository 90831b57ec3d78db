// glTF 2.0 (Khronos, "glTF 2.0 Specification", 2021): .gltf with external
// or embedded (data: URI) buffers and binary .glb, through tinygltf.
//
// tinygltf parses the JSON and reads the buffers; everything a bake depends
// on is checked here, because tinygltf leaves most of it to its caller:
// every accessor, buffer view and index is range-checked before it is read,
// node hierarchies are walked with an explicit stack and cycle detection,
// and each failure names the file, the part and the reason.
//
// What is read (load.hpp has the contract): every node with a mesh in the
// scene (the default scene, else scene 0, else every root node), in
// depth-first order, with its world matrix applied; one MeshPart per node,
// and a material range per primitive (its material's name).
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <glm/gtc/matrix_inverse.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <map>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <string_view>
#include <tuple>
#include <vector>

#include "load/parsers.hpp"
#include "load/tinygltf.hpp"
#include "nmbake/color.hpp"
#include "nmbake/memory.hpp"

namespace nmbake::load_detail {

namespace {

constexpr int kModeTriangles = TINYGLTF_MODE_TRIANGLES;

// Peak memory of reading a glTF file per byte of it (the whole process,
// measured with /usr/bin/time, rounded up): a 200 MB .gltf holding one data:
// URI peaked at 1.04 GB (5.2 x), a 150 MB .glb at 306 MB (2.0 x: the file,
// and its BIN chunk copied into the buffer).
constexpr std::uint64_t kGltfParseBytesPerByte = 6;
constexpr std::uint64_t kGlbParseBytesPerByte = 3;

// The world-space transform of one node, with what normals and tangents need.
struct NodeTransform {
  glm::dmat4 matrix{1.0};
  glm::dmat3 normal_matrix{1.0};  // inverse transpose of the upper 3x3
  bool mirrored = false;          // determinant < 0: winding and tangent sign flip
};

NodeTransform make_transform(const glm::dmat4& matrix) {
  NodeTransform t;
  t.matrix = matrix;
  const glm::dmat3 linear(matrix);
  const double det = glm::determinant(linear);
  t.mirrored = det < 0.0;
  // A singular matrix (scale 0 on an axis) has no inverse; its normals are
  // then as undefined as the flattened geometry, and normalize_normals()
  // replaces the zero-length ones it leaves.
  t.normal_matrix = det != 0.0 ? glm::inverseTranspose(linear) : glm::dmat3(0.0);
  return t;
}

glm::dmat4 local_matrix(const tinygltf::Node& node) {
  if (node.matrix.size() == 16) return glm::make_mat4(node.matrix.data());  // column-major, as glTF stores it
  glm::dmat4 m(1.0);
  if (node.translation.size() == 3) {
    m = glm::translate(m, glm::dvec3(node.translation[0], node.translation[1], node.translation[2]));
  }
  if (node.rotation.size() == 4) {
    // glTF stores x, y, z, w; glm's constructor takes w first.
    const glm::dquat q(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]);
    m = m * glm::mat4_cast(glm::normalize(q));
  }
  if (node.scale.size() == 3) m = glm::scale(m, glm::dvec3(node.scale[0], node.scale[1], node.scale[2]));
  return m;
}

std::string number_text(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", value);
  return text;
}

std::size_t component_bytes(int component_type) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return 2;
    case TINYGLTF_COMPONENT_TYPE_INT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return 4;
    default:
      return 0;
  }
}

const char* component_name(int component_type) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
      return "byte";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return "unsigned byte";
    case TINYGLTF_COMPONENT_TYPE_SHORT:
      return "short";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return "unsigned short";
    case TINYGLTF_COMPONENT_TYPE_INT:
      return "int";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
      return "unsigned int";
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return "float";
    case TINYGLTF_COMPONENT_TYPE_DOUBLE:
      return "double";
    default:
      return "unknown component type";
  }
}

// Bytes [first, first + stride * (count - 1) + element) of a buffer view,
// checked against the view and the buffer.
struct Span {
  const unsigned char* data = nullptr;
  std::size_t stride = 0;
};

std::string locate_view(const tinygltf::Model& model, int view_index, std::size_t offset, std::size_t count,
                        std::size_t element_bytes, std::size_t explicit_stride, Span& out) {
  if (view_index < 0 || static_cast<std::size_t>(view_index) >= model.bufferViews.size()) {
    return "buffer view " + std::to_string(view_index) + " does not exist";
  }
  const tinygltf::BufferView& view = model.bufferViews[static_cast<std::size_t>(view_index)];
  if (view.buffer < 0 || static_cast<std::size_t>(view.buffer) >= model.buffers.size()) {
    return "buffer view " + std::to_string(view_index) + " names buffer " + std::to_string(view.buffer) +
           ", which does not exist";
  }
  const std::vector<unsigned char>& data = model.buffers[static_cast<std::size_t>(view.buffer)].data;
  if (view.byteOffset > data.size() || view.byteLength > data.size() - view.byteOffset) {
    return "buffer view " + std::to_string(view_index) + " (bytes " + std::to_string(view.byteOffset) + "+" +
           std::to_string(view.byteLength) + ") lies outside buffer " + std::to_string(view.buffer) + " (" +
           std::to_string(data.size()) + " bytes)";
  }
  const std::size_t stride = explicit_stride != 0 ? explicit_stride : element_bytes;
  if (stride < element_bytes) {
    return "buffer view " + std::to_string(view_index) + " has a byte stride of " + std::to_string(stride) +
           ", less than its " + std::to_string(element_bytes) + "-byte elements";
  }
  if (count > 0) {
    // Divided, not multiplied, so that a hostile count cannot overflow.
    const std::size_t available = view.byteLength >= offset ? view.byteLength - offset : 0;
    if (available < element_bytes || (count - 1) > (available - element_bytes) / stride) {
      return std::to_string(count) + " elements of " + std::to_string(element_bytes) + " bytes at offset " +
             std::to_string(offset) + " do not fit in buffer view " + std::to_string(view_index) + " (" +
             std::to_string(view.byteLength) + " bytes)";
    }
  }
  out.data = data.data() + view.byteOffset + offset;
  out.stride = stride;
  return {};
}

double read_component(const unsigned char* p, int component_type, bool normalized) {
  // Normalised integers map to [0, 1] or [-1, 1] as the specification's
  // "Animations" / "Meshes" sections define (signed: max(c / MAX, -1)).
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: {
      float f;
      std::memcpy(&f, p, 4);
      return f;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return normalized ? p[0] / 255.0 : p[0];
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      const auto v = static_cast<std::int8_t>(p[0]);
      return normalized ? std::max(v / 127.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      std::uint16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? v / 65535.0 : v;
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      std::int16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? std::max(v / 32767.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
      std::uint32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
    case TINYGLTF_COMPONENT_TYPE_INT: {
      std::int32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
    default:
      return 0.0;
  }
}

std::uint64_t read_index(const unsigned char* p, int component_type) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return p[0];
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      std::uint16_t v;
      std::memcpy(&v, p, 2);
      return v;
    }
    default: {
      std::uint32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
  }
}

// Reads an accessor of `components` reals per element (sparse accessors
// included: the base view, or zeros without one, then the listed
// substitutions). `float_only`: integer types are refused (positions,
// normals, tangents); otherwise normalised integers are accepted too
// (texture coordinates). Each element goes to sink(index, const float*)
// (a substituted one twice: base value, then the substitute), so a large
// mesh is decoded straight into its arrays. An empty string on success,
// else the reason; `count` is the element count.
// With `validate_only` nothing is decoded: every check that needs no
// decoding is made (the caller can then size its arrays safely).
template <typename Sink>
std::string read_accessor(const tinygltf::Model& model, int accessor_index, int components, bool float_only,
                          std::size_t& count, Sink&& sink, bool validate_only = false) {
  if (accessor_index < 0 || static_cast<std::size_t>(accessor_index) >= model.accessors.size()) {
    return "accessor " + std::to_string(accessor_index) + " does not exist";
  }
  const tinygltf::Accessor& a = model.accessors[static_cast<std::size_t>(accessor_index)];
  const std::string name = "accessor " + std::to_string(accessor_index);
  const int type_components = tinygltf::GetNumComponentsInType(static_cast<std::uint32_t>(a.type));
  if (type_components != components) {
    return name + " has " + std::to_string(std::max(type_components, 0)) +
           " components per element, expected " + std::to_string(components);
  }
  const bool is_float = a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT;
  const bool integer_ok = !float_only && a.normalized && a.componentType != TINYGLTF_COMPONENT_TYPE_INT &&
                          a.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
  if (!is_float && !integer_ok) {
    return name + ": component type " + std::string(component_name(a.componentType)) +
           (a.normalized ? " (normalized)" : "") + " is not supported here (expected float" +
           (float_only ? "" : ", or normalized unsigned byte or short") + ")";
  }
  const std::size_t component_size = component_bytes(a.componentType);
  const std::size_t element_bytes = component_size * static_cast<std::size_t>(components);
  count = a.count;
  float element_values[4] = {0.0f, 0.0f, 0.0f, 0.0f};
  if (a.bufferView >= 0) {
    Span span;
    const std::size_t stride =
        static_cast<std::size_t>(a.bufferView < static_cast<int>(model.bufferViews.size())
                                     ? model.bufferViews[static_cast<std::size_t>(a.bufferView)].byteStride
                                     : 0);
    if (std::string e = locate_view(model, a.bufferView, a.byteOffset, count, element_bytes, stride, span);
        !e.empty()) {
      return name + ": " + e;
    }
    for (std::size_t i = 0; i < count && !validate_only; ++i) {
      const unsigned char* element = span.data + i * span.stride;
      for (int c = 0; c < components; ++c) {
        element_values[c] = static_cast<float>(read_component(
            element + static_cast<std::size_t>(c) * component_size, a.componentType, a.normalized));
      }
      sink(i, element_values);
    }
  } else if (!a.sparse.isSparse) {
    return name + " has no buffer view and is not sparse";
  } else if (!validate_only) {
    // A sparse accessor without a base view starts as zeros.
    for (std::size_t i = 0; i < count; ++i) sink(i, element_values);
  }
  if (a.sparse.isSparse) {
    const auto sparse_count = static_cast<std::size_t>(std::max(a.sparse.count, 0));
    const int index_type = a.sparse.indices.componentType;
    if (index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
        index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
        index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
      return name + ": sparse indices of type " + component_name(index_type) + " are not supported";
    }
    Span indices;
    Span values;
    if (std::string e = locate_view(model, a.sparse.indices.bufferView,
                                    static_cast<std::size_t>(std::max(a.sparse.indices.byteOffset, 0)),
                                    sparse_count, component_bytes(index_type), 0, indices);
        !e.empty()) {
      return name + ": sparse indices: " + e;
    }
    if (std::string e = locate_view(model, a.sparse.values.bufferView,
                                    static_cast<std::size_t>(std::max(a.sparse.values.byteOffset, 0)),
                                    sparse_count, element_bytes, 0, values);
        !e.empty()) {
      return name + ": sparse values: " + e;
    }
    for (std::size_t i = 0; i < sparse_count && !validate_only; ++i) {
      const std::uint64_t target = read_index(indices.data + i * indices.stride, index_type);
      if (target >= count) {
        return name + ": sparse index " + std::to_string(target) + " is out of range (" +
               std::to_string(count) + " elements)";
      }
      for (int c = 0; c < components; ++c) {
        element_values[c] = static_cast<float>(
            read_component(values.data + i * values.stride + static_cast<std::size_t>(c) * component_size,
                           a.componentType, a.normalized));
      }
      sink(static_cast<std::size_t>(target), element_values);
    }
  }
  return {};
}

std::string read_indices(const tinygltf::Model& model, int accessor_index, std::vector<std::uint32_t>& out) {
  if (accessor_index < 0 || static_cast<std::size_t>(accessor_index) >= model.accessors.size()) {
    return "index accessor " + std::to_string(accessor_index) + " does not exist";
  }
  const tinygltf::Accessor& a = model.accessors[static_cast<std::size_t>(accessor_index)];
  const std::string name = "index accessor " + std::to_string(accessor_index);
  if (a.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
      a.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
      a.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
    return name + ": component type " + std::string(component_name(a.componentType)) +
           " is not an index type (unsigned byte, short or int)";
  }
  if (a.type != TINYGLTF_TYPE_SCALAR) return name + " is not SCALAR";
  if (a.sparse.isSparse) return name + " is sparse, which indices may not be";
  Span span;
  const std::size_t element_bytes = component_bytes(a.componentType);
  const std::size_t stride = a.bufferView >= 0 && a.bufferView < static_cast<int>(model.bufferViews.size())
                                 ? model.bufferViews[static_cast<std::size_t>(a.bufferView)].byteStride
                                 : 0;
  if (std::string e = locate_view(model, a.bufferView, a.byteOffset, a.count, element_bytes, stride, span);
      !e.empty()) {
    return name + ": " + e;
  }
  out.resize(a.count);
  for (std::size_t i = 0; i < a.count; ++i) {
    const std::uint64_t v = read_index(span.data + i * span.stride, a.componentType);
    out[i] = static_cast<std::uint32_t>(std::min<std::uint64_t>(v, 0xffffffffu));
  }
  return {};
}

std::string list_uv_sets(const tinygltf::Primitive& primitive) {
  std::string sets;
  for (const auto& [attribute, accessor] : primitive.attributes) {
    (void)accessor;
    if (attribute.rfind("TEXCOORD_", 0) == 0) sets += (sets.empty() ? "" : ", ") + attribute;
  }
  return sets.empty() ? std::string("none") : sets;
}

// Reads everything of the file the bake needs, node by node.
std::string decode_uri(const std::string& uri);

// Empty when an image's decoded uri may be read: a relative path that stays
// under the glTF's folder (the rule of buffers, README "Mesh formats");
// whether the file is there is found when a bake reads it.
std::string image_uri_problem(const std::string& relative) {
  if (relative.empty()) return "the uri is empty";
  if (relative.find('\0') != std::string::npos) return "the uri holds a NUL byte";
  if (relative.front() == '/')
    return "the uri is an absolute path (images are read only from under the glTF's folder)";
  const std::filesystem::path normal = std::filesystem::path(relative).lexically_normal();
  if (!normal.empty() && *normal.begin() == "..") return "the uri leaves the glTF's folder";
  return {};
}

class GltfReader {
 public:
  GltfReader(const std::string& path, const tinygltf::Model& model, const LoadOptions& options, Mesh& out,
             LoadStats& stats)
      : path_(path), model_(model), options_(options), out_(out), stats_(stats) {}

  Status read() {
    for (const std::string& extension : model_.extensionsRequired) {
      NMBAKE_TRY(check_extension(extension, "the file"));
    }
    std::vector<int> roots;
    NMBAKE_TRY(scene_roots(roots));
    // How many nodes instance each mesh: a shared mesh's name cannot name a part.
    mesh_users_.assign(model_.meshes.size(), 0);
    for (const tinygltf::Node& node : model_.nodes) {
      if (node.mesh >= 0 && static_cast<std::size_t>(node.mesh) < model_.meshes.size()) {
        ++mesh_users_[static_cast<std::size_t>(node.mesh)];
      }
    }
    NMBAKE_TRY(walk(roots));
    if (out_.indices.empty()) {
      return Status::bad_input(path_ + ": no triangles (nodes with a mesh: " + std::to_string(node_meshes_) +
                               "; points and lines are skipped)");
    }
    // Attributes only some primitives had are dropped as a whole (normals:
    // recomputed later) or were an error already (UVs, tangents).
    if (!all_normals_) out_.normals.clear();
    if (!all_uvs_) out_.uvs.clear();
    if (!all_tangents_) out_.tangents.clear();
    // Vertex colours: white where a primitive has no COLOR_0 (the
    // specification's default), none at all when no primitive has them.
    if (!any_colors_) out_.colors.clear();
    if (options_.material_defs) read_material_defs();
    stats_.triangles = out_.triangle_count();
    stats_.polygons = stats_.triangles;
    return Status::ok();
  }

 private:
  Status error(const std::string& part, const std::string& reason) const {
    return Status::bad_input(path_ + ": " + (part.empty() ? "" : "part '" + part + "': ") + reason);
  }

  Status check_extension(const std::string& extension, const std::string& where) const {
    if (extension == "KHR_draco_mesh_compression") {
      return Status::bad_input(path_ + ": " + where +
                               " uses KHR_draco_mesh_compression: Draco-compressed meshes are not supported");
    }
    if (extension == "EXT_meshopt_compression" || extension == "KHR_meshopt_compression") {
      return Status::bad_input(path_ + ": " + where + " uses " + extension +
                               ": compressed buffers are not supported");
    }
    return Status::ok();
  }

  Status scene_roots(std::vector<int>& roots) const {
    if (!model_.scenes.empty()) {
      const int scene = model_.defaultScene >= 0 ? model_.defaultScene : 0;
      if (static_cast<std::size_t>(scene) >= model_.scenes.size()) {
        return Status::bad_input(path_ + ": the default scene " + std::to_string(scene) + " does not exist");
      }
      roots = model_.scenes[static_cast<std::size_t>(scene)].nodes;
      return Status::ok();
    }
    // No scene: every node that is nobody's child is a root, as viewers do.
    std::vector<bool> is_child(model_.nodes.size(), false);
    for (const tinygltf::Node& node : model_.nodes) {
      for (int child : node.children) {
        if (child >= 0 && static_cast<std::size_t>(child) < is_child.size())
          is_child[static_cast<std::size_t>(child)] = true;
      }
    }
    for (std::size_t n = 0; n < model_.nodes.size(); ++n) {
      if (!is_child[n]) roots.push_back(static_cast<int>(n));
    }
    return Status::ok();
  }

  // Depth first with an explicit stack: a hostile file may nest nodes deeper
  // than the call stack would survive. A node reached twice (a cycle, or two
  // parents, which glTF forbids) is an error.
  Status walk(const std::vector<int>& roots) {
    struct Entry {
      int node;
      glm::dmat4 parent;
    };
    std::vector<bool> visited(model_.nodes.size(), false);
    std::vector<Entry> stack;
    for (auto it = roots.rbegin(); it != roots.rend(); ++it) stack.push_back({*it, glm::dmat4(1.0)});
    while (!stack.empty()) {
      const Entry entry = stack.back();
      stack.pop_back();
      if (entry.node < 0 || static_cast<std::size_t>(entry.node) >= model_.nodes.size()) {
        return Status::bad_input(path_ + ": node " + std::to_string(entry.node) + " does not exist");
      }
      const auto n = static_cast<std::size_t>(entry.node);
      if (visited[n]) {
        return Status::bad_input(path_ + ": node " + std::to_string(entry.node) +
                                 " is reached twice in the node hierarchy (a cycle, or two parents)");
      }
      visited[n] = true;
      const tinygltf::Node& node = model_.nodes[n];
      NMBAKE_TRY(check_transform(entry.node, node));
      const glm::dmat4 world = entry.parent * local_matrix(node);
      if (node.mesh >= 0) NMBAKE_TRY(read_node_mesh(entry.node, make_transform(world)));
      for (auto it = node.children.rbegin(); it != node.children.rend(); ++it) stack.push_back({*it, world});
    }
    return Status::ok();
  }

  // A node's own transform must be a finite affine one: a projective matrix
  // (a last row other than 0 0 0 1, the all-zero matrix among them) has no
  // meaning for a mesh's positions and divides nothing here, a rotation of
  // length 0 cannot be normalised, and tinygltf ignores a matrix of the
  // wrong length silently.
  Status check_transform(int node_index, const tinygltf::Node& node) const {
    const auto refuse = [&](const std::string& reason) {
      return Status::bad_input(path_ + ": node " + std::to_string(node_index) +
                               (node.name.empty() ? "" : " ('" + printable_text(node.name) + "')") + ": " +
                               reason);
    };
    const auto finite = [](const std::vector<double>& v) {
      return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
    };
    if (!node.matrix.empty()) {
      if (node.matrix.size() != 16) {
        return refuse("its matrix has " + std::to_string(node.matrix.size()) + " numbers, not 16");
      }
      if (!finite(node.matrix)) return refuse("its matrix holds a number that is not finite");
      // Column-major: the last row is elements 3, 7, 11 and 15.
      const std::vector<double>& m = node.matrix;
      if (m[3] != 0.0 || m[7] != 0.0 || m[11] != 0.0 || m[15] != 1.0) {
        return refuse("its matrix is not affine (last row " + number_text(m[3]) + " " + number_text(m[7]) +
                      " " + number_text(m[11]) + " " + number_text(m[15]) +
                      ", expected 0 0 0 1): a zero or projective matrix places no mesh");
      }
    }
    for (const auto& [values, count, what] : {std::tuple{&node.translation, std::size_t{3}, "translation"},
                                              std::tuple{&node.rotation, std::size_t{4}, "rotation"},
                                              std::tuple{&node.scale, std::size_t{3}, "scale"}}) {
      if (values->empty()) continue;
      if (values->size() != count) {
        return refuse(std::string("its ") + what + " has " + std::to_string(values->size()) +
                      " numbers, not " + std::to_string(count));
      }
      if (!finite(*values)) return refuse(std::string("its ") + what + " holds a number that is not finite");
    }
    if (node.rotation.size() == 4 && node.rotation[0] == 0.0 && node.rotation[1] == 0.0 &&
        node.rotation[2] == 0.0 && node.rotation[3] == 0.0) {
      return refuse("its rotation is the zero quaternion, which is no rotation");
    }
    return Status::ok();
  }

  std::string part_name(int node_index) const {
    const tinygltf::Node& node = model_.nodes[static_cast<std::size_t>(node_index)];
    if (!node.name.empty()) return node.name;
    const tinygltf::Mesh& mesh = model_.meshes[static_cast<std::size_t>(node.mesh)];
    if (!mesh.name.empty() && mesh_users_[static_cast<std::size_t>(node.mesh)] == 1) return mesh.name;
    return "node" + std::to_string(node_index);
  }

  Status read_node_mesh(int node_index, const NodeTransform& transform) {
    const tinygltf::Node& node = model_.nodes[static_cast<std::size_t>(node_index)];
    if (static_cast<std::size_t>(node.mesh) >= model_.meshes.size()) {
      return Status::bad_input(path_ + ": node " + std::to_string(node_index) + " names mesh " +
                               std::to_string(node.mesh) + ", which does not exist");
    }
    ++node_meshes_;
    const std::string name = part_name(node_index);
    if (!part_names_.emplace(name, node_index).second) {
      return Status::bad_input(path_ + ": two parts are named '" + name + "' (nodes " +
                               std::to_string(part_names_[name]) + " and " + std::to_string(node_index) +
                               "): part names must be unique");
    }
    const std::size_t first_triangle = out_.triangle_count();
    const tinygltf::Mesh& mesh = model_.meshes[static_cast<std::size_t>(node.mesh)];
    for (std::size_t p = 0; p < mesh.primitives.size(); ++p) {
      const std::size_t primitive_first = out_.triangle_count();
      std::string material;
      NMBAKE_TRY(material_name(name, mesh.primitives[p], p, material));
      NMBAKE_TRY(read_primitive(name, mesh.primitives[p], p, transform));
      append_range(out_.materials, material, static_cast<std::uint32_t>(primitive_first),
                   static_cast<std::uint32_t>(out_.triangle_count() - primitive_first));
    }
    const std::size_t triangle_count = out_.triangle_count() - first_triangle;
    if (triangle_count > 0) {
      out_.parts.push_back(MeshPart{name, static_cast<std::uint32_t>(first_triangle),
                                    static_cast<std::uint32_t>(triangle_count)});
    }
    return Status::ok();
  }

  // A primitive's material: its name, "material N" when it has none, "" when
  // the primitive has no material.
  Status material_name(const std::string& part, const tinygltf::Primitive& primitive, std::size_t index,
                       std::string& name) const {
    name.clear();
    if (primitive.material < 0) return Status::ok();
    const auto m = static_cast<std::size_t>(primitive.material);
    if (m >= model_.materials.size()) {
      return error(part, "primitive " + std::to_string(index) + ": material " +
                             std::to_string(primitive.material) + " does not exist");
    }
    name = model_.materials[m].name.empty() ? "material " + std::to_string(m) : model_.materials[m].name;
    return Status::ok();
  }

  // ------------------------------------------------------------ materials

  // The texture of a textureInfo: its image's file (under the glTF's folder,
  // as buffers), sampler wrap modes and KHR_texture_transform.
  TextureRef texture_ref(int texture_index, int tex_coord, const tinygltf::ExtensionMap& extensions) {
    TextureRef ref;
    ref.texcoord = tex_coord;
    if (texture_index < 0 || static_cast<std::size_t>(texture_index) >= model_.textures.size()) {
      ref.problem = "texture " + std::to_string(texture_index) + " does not exist";
      return ref;
    }
    const tinygltf::Texture& texture = model_.textures[static_cast<std::size_t>(texture_index)];
    if (texture.sampler >= 0 && static_cast<std::size_t>(texture.sampler) < model_.samplers.size()) {
      const tinygltf::Sampler& sampler = model_.samplers[static_cast<std::size_t>(texture.sampler)];
      const auto wrap = [](int mode) {
        return mode == TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE     ? TextureWrap::clamp
               : mode == TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT ? TextureWrap::mirror
                                                               : TextureWrap::repeat;
      };
      ref.wrap_u = wrap(sampler.wrapS);
      ref.wrap_v = wrap(sampler.wrapT);
    }
    if (const auto it = extensions.find("KHR_texture_transform"); it != extensions.end()) {
      const tinygltf::Value& t = it->second;
      const auto number = [&](const tinygltf::Value& v, double fallback) {
        return v.IsNumber() ? v.GetNumberAsDouble() : fallback;
      };
      if (t.Has("offset") && t.Get("offset").IsArray() && t.Get("offset").ArrayLen() == 2) {
        ref.offset = glm::vec2(static_cast<float>(number(t.Get("offset").Get(0), 0.0)),
                               static_cast<float>(number(t.Get("offset").Get(1), 0.0)));
      }
      if (t.Has("scale") && t.Get("scale").IsArray() && t.Get("scale").ArrayLen() == 2) {
        ref.scale = glm::vec2(static_cast<float>(number(t.Get("scale").Get(0), 1.0)),
                              static_cast<float>(number(t.Get("scale").Get(1), 1.0)));
      }
      if (t.Has("rotation")) ref.rotation = static_cast<float>(number(t.Get("rotation"), 0.0));
      if (t.Has("texCoord")) ref.texcoord = static_cast<int>(number(t.Get("texCoord"), tex_coord));
      if (!std::isfinite(ref.offset.x) || !std::isfinite(ref.offset.y) || !std::isfinite(ref.scale.x) ||
          !std::isfinite(ref.scale.y) || !std::isfinite(ref.rotation)) {
        ref.problem = "KHR_texture_transform holds a number that is not finite";
        return ref;
      }
    }
    const int source = texture.source;
    if (source < 0 || static_cast<std::size_t>(source) >= model_.images.size()) {
      ref.problem = "texture " + std::to_string(texture_index) + " has no image";
      return ref;
    }
    const tinygltf::Image& image = model_.images[static_cast<std::size_t>(source)];
    if (image.bufferView >= 0 || !image.image.empty()) {
      std::string problem;
      ref.embedded = embedded_image(static_cast<std::size_t>(source), problem);
      if (ref.embedded < 0) ref.problem = "image " + std::to_string(source) + ": " + problem;
      return ref;
    }
    const std::string relative = decode_uri(image.uri);
    if (std::string problem = image_uri_problem(relative); !problem.empty()) {
      ref.problem =
          "image " + std::to_string(source) + " (uri '" + printable_text(image.uri) + "'): " + problem;
      return ref;
    }
    ref.path =
        (std::filesystem::path(path_).parent_path() / std::filesystem::path(relative).lexically_normal())
            .string();
    return ref;
  }

  // Image `source` (a buffer view's bytes, or a data: URI's that
  // keep_image_bytes kept) as Mesh::embedded_images[result], copied once;
  // -1 and `problem` when its buffer view does not lie inside its buffer.
  int embedded_image(std::size_t source, std::string& problem) {
    if (const auto it = embedded_.find(source); it != embedded_.end()) return it->second;
    const tinygltf::Image& image = model_.images[source];
    EmbeddedImage embedded;
    embedded.format = image.mimeType;
    if (image.bufferView >= 0) {
      const auto view_index = static_cast<std::size_t>(image.bufferView);
      if (view_index >= model_.bufferViews.size()) {
        problem = "bufferView " + std::to_string(view_index) + " does not exist";
        return -1;
      }
      const tinygltf::BufferView& view = model_.bufferViews[view_index];
      if (view.buffer < 0 || static_cast<std::size_t>(view.buffer) >= model_.buffers.size()) {
        problem = "bufferView " + std::to_string(view_index) + " names no buffer";
        return -1;
      }
      const std::vector<unsigned char>& data = model_.buffers[static_cast<std::size_t>(view.buffer)].data;
      if (view.byteOffset > data.size() || view.byteLength > data.size() - view.byteOffset) {
        problem = "bufferView " + std::to_string(view_index) + " (" + std::to_string(view.byteLength) +
                  " bytes at " + std::to_string(view.byteOffset) + ") lies outside its buffer of " +
                  std::to_string(data.size()) + " bytes";
        return -1;
      }
      const auto first = data.begin() + static_cast<std::ptrdiff_t>(view.byteOffset);
      embedded.bytes.assign(first, first + static_cast<std::ptrdiff_t>(view.byteLength));
    } else {
      embedded.bytes = image.image;
    }
    const int result = static_cast<int>(out_.embedded_images.size());
    out_.embedded_images.push_back(std::move(embedded));
    embedded_.emplace(source, result);
    return result;
  }

  // Mesh::material_defs for every material a primitive used.
  void read_material_defs() {
    for (std::size_t m = 0; m < model_.materials.size(); ++m) {
      const tinygltf::Material& source = model_.materials[m];
      Material def;
      def.name = source.name.empty() ? "material " + std::to_string(m) : source.name;
      const bool used = std::any_of(out_.materials.begin(), out_.materials.end(),
                                    [&](const MeshPart& range) { return range.name == def.name; });
      if (!used || out_.material_def(def.name) != nullptr) continue;
      const tinygltf::PbrMetallicRoughness& pbr = source.pbrMetallicRoughness;
      if (pbr.baseColorFactor.size() == 4) {
        def.base_color = glm::vec4(pbr.baseColorFactor[0], pbr.baseColorFactor[1], pbr.baseColorFactor[2],
                                   pbr.baseColorFactor[3]);
        def.has_color = true;
      }
      if (source.alphaMode == "OPAQUE" || source.alphaMode.empty()) def.base_color.a = 1.0f;
      def.roughness = static_cast<float>(pbr.roughnessFactor);
      def.metallic = static_cast<float>(pbr.metallicFactor);
      if (pbr.baseColorTexture.index >= 0) {
        def.base_color_texture = texture_ref(pbr.baseColorTexture.index, pbr.baseColorTexture.texCoord,
                                             pbr.baseColorTexture.extensions);
        if (source.alphaMode == "BLEND" || source.alphaMode == "MASK") {
          def.opacity_texture = def.base_color_texture;
          def.opacity_texture.channel = 3;
        }
      }
      if (pbr.metallicRoughnessTexture.index >= 0) {
        def.roughness_texture =
            texture_ref(pbr.metallicRoughnessTexture.index, pbr.metallicRoughnessTexture.texCoord,
                        pbr.metallicRoughnessTexture.extensions);
        def.roughness_texture.channel = 1;  // G
        def.metallic_texture = def.roughness_texture;
        def.metallic_texture.channel = 2;  // B
      }
      if (source.emissiveFactor.size() == 3) {
        def.emissive =
            glm::vec3(source.emissiveFactor[0], source.emissiveFactor[1], source.emissiveFactor[2]);
      }
      if (source.emissiveTexture.index >= 0) {
        def.emissive_texture = texture_ref(source.emissiveTexture.index, source.emissiveTexture.texCoord,
                                           source.emissiveTexture.extensions);
      }
      if (source.normalTexture.index >= 0) {
        def.normal_texture = texture_ref(source.normalTexture.index, source.normalTexture.texCoord,
                                         source.normalTexture.extensions);
        def.normal_scale = static_cast<float>(source.normalTexture.scale);
      }
      if (!std::isfinite(def.base_color.r) || !std::isfinite(def.base_color.g) ||
          !std::isfinite(def.base_color.b) || !std::isfinite(def.base_color.a) ||
          !std::isfinite(def.roughness) || !std::isfinite(def.metallic) || !std::isfinite(def.normal_scale) ||
          !std::isfinite(def.emissive.r) || !std::isfinite(def.emissive.g) ||
          !std::isfinite(def.emissive.b)) {
        def.base_color = glm::vec4(1.0f);
        def.roughness = 1.0f;
        def.metallic = 0.0f;
        def.emissive = glm::vec3(0.0f);
        def.normal_scale = 1.0f;
      }
      out_.material_defs.push_back(std::move(def));
    }
  }

  Status read_primitive(const std::string& part, const tinygltf::Primitive& primitive, std::size_t index,
                        const NodeTransform& transform) {
    const std::string where = "primitive " + std::to_string(index) + ": ";
    for (const auto& [extension, value] : primitive.extensions) {
      (void)value;
      NMBAKE_TRY(check_extension(extension, "part '" + part + "' " + where.substr(0, where.size() - 2)));
    }
    const int mode = primitive.mode < 0 ? kModeTriangles : primitive.mode;
    const bool triangles = mode == TINYGLTF_MODE_TRIANGLES || mode == TINYGLTF_MODE_TRIANGLE_STRIP ||
                           mode == TINYGLTF_MODE_TRIANGLE_FAN;
    const auto attribute = [&](const std::string& key) {
      const auto it = primitive.attributes.find(key);
      return it == primitive.attributes.end() ? -1 : it->second;
    };
    const int position_accessor = attribute("POSITION");
    if (position_accessor < 0) return error(part, where + "no POSITION attribute");
    if (static_cast<std::size_t>(position_accessor) >= model_.accessors.size()) {
      return error(part,
                   where + "POSITION: accessor " + std::to_string(position_accessor) + " does not exist");
    }
    // POSITION must have real data: its count then cannot exceed what the
    // file holds, so the arrays sized from it are bounded by the file (a
    // sparse accessor over zeros could claim any count).
    if (model_.accessors[static_cast<std::size_t>(position_accessor)].bufferView < 0) {
      return error(part, where + "POSITION without a buffer view (sparse over zeros) is not supported");
    }
    std::size_t vertex_count = 0;
    const auto ignore = [](std::size_t, const float*) {};
    if (std::string e = read_accessor(model_, position_accessor, 3, true, vertex_count, ignore, true);
        !e.empty()) {
      return error(part, where + "POSITION: " + e);
    }
    // Every attribute must have one element per position.
    const auto check_count = [&](int accessor, const std::string& key) -> std::string {
      if (accessor < 0 || static_cast<std::size_t>(accessor) >= model_.accessors.size()) {
        return key + ": accessor " + std::to_string(accessor) + " does not exist";
      }
      const std::size_t n = model_.accessors[static_cast<std::size_t>(accessor)].count;
      if (n != vertex_count) {
        return key + " has " + std::to_string(n) + " elements, POSITION " + std::to_string(vertex_count);
      }
      return {};
    };
    std::vector<std::uint32_t> indices;
    if (primitive.indices >= 0) {
      if (std::string e = read_indices(model_, primitive.indices, indices); !e.empty()) {
        return error(part, where + e);
      }
      for (std::size_t i = 0; i < indices.size(); ++i) {
        if (indices[i] >= vertex_count) {
          return error(part, where + "index " + std::to_string(i) + " is " + std::to_string(indices[i]) +
                                 ", out of range (" + std::to_string(vertex_count) + " vertices)");
        }
      }
    } else {
      indices.resize(vertex_count);
      for (std::size_t i = 0; i < vertex_count; ++i) indices[i] = static_cast<std::uint32_t>(i);
    }
    if (!triangles) {
      // Points and lines have no surface to bake: skipped, counted per element.
      const std::size_t n = indices.size();
      std::size_t elements = n;
      if (mode == TINYGLTF_MODE_LINE) elements = n / 2;
      if (mode == TINYGLTF_MODE_LINE_STRIP) elements = n > 0 ? n - 1 : 0;
      stats_.degenerate_faces += elements;
      return Status::ok();
    }

    // Which attributes this primitive brings; an attribute that some
    // primitives lack is dropped (normals) or an error (UVs, tangents).
    const int normal_accessor = options_.keep_normals ? attribute("NORMAL") : -1;
    if (normal_accessor < 0) all_normals_ = false;
    int uv_accessor = -1;
    const std::string uv_key = "TEXCOORD_" + std::to_string(options_.uv_set);
    if (options_.keep_uvs) {
      uv_accessor = attribute(uv_key);
      if (uv_accessor >= 0) {
        if (!all_uvs_) return error(part, where + "has " + uv_key + " but an earlier primitive has no UVs");
        any_uvs_ = true;
      } else {
        // A file with no texture coordinates at all is like an OBJ without
        // vt (the low mesh may be unwrapped); asking for a set that is not
        // there, or having it on some primitives only, is an error.
        if (options_.uv_set != 0 || list_uv_sets(primitive) != "none" || any_uvs_) {
          return error(part, where + "UV set " + std::to_string(options_.uv_set) + " (" + uv_key +
                                 ") is missing; this primitive has: " + list_uv_sets(primitive));
        }
        all_uvs_ = false;
      }
    } else {
      all_uvs_ = false;
    }
    int tangent_accessor = -1;
    if (options_.keep_tangents) {
      tangent_accessor = attribute("TANGENT");
      if (tangent_accessor >= 0 && any_without_tangents_)
        return error(part, where + "has TANGENT but an earlier primitive has none");
      if (tangent_accessor < 0 && any_tangents_)
        return error(part, where + "has no TANGENT but an earlier primitive has");
      if (tangent_accessor >= 0) {
        any_tangents_ = true;
      } else {
        any_without_tangents_ = true;
        all_tangents_ = false;
      }
    } else {
      all_tangents_ = false;
    }
    const int color_accessor = options_.keep_colors ? attribute("COLOR_0") : -1;
    int color_components = 0;
    if (color_accessor >= 0) {
      if (static_cast<std::size_t>(color_accessor) >= model_.accessors.size()) {
        return error(part, where + "COLOR_0: accessor " + std::to_string(color_accessor) + " does not exist");
      }
      color_components = tinygltf::GetNumComponentsInType(
          static_cast<std::uint32_t>(model_.accessors[static_cast<std::size_t>(color_accessor)].type));
      if (color_components != 3 && color_components != 4) {
        return error(part, where + "COLOR_0 has " + std::to_string(std::max(color_components, 0)) +
                               " components per element, expected 3 (RGB) or 4 (RGBA)");
      }
    }
    for (const auto& [accessor, key] :
         {std::pair{normal_accessor, std::string("NORMAL")}, std::pair{uv_accessor, uv_key},
          std::pair{tangent_accessor, std::string("TANGENT")},
          std::pair{color_accessor, std::string("COLOR_0")}}) {
      if (accessor < 0) continue;
      if (std::string e = check_count(accessor, key); !e.empty()) return error(part, where + e);
    }
    // Indices were read (and range-checked) from real data; a sparse
    // attribute's count equals POSITION's, which is bounded the same way.

    // The primitive's vertices, as the file has them (split where the file
    // splits them), in world space, decoded straight into the mesh.
    if (out_.positions.size() + vertex_count > 0xffffffffu)
      return error(part, where + "more than 2^32 vertices in the file");
    const auto base = static_cast<std::uint32_t>(out_.positions.size());
    std::size_t count = 0;
    out_.positions.resize(base + vertex_count);
    if (std::string e = read_accessor(model_, position_accessor, 3, true, count,
                                      [&](std::size_t v, const float* p) {
                                        out_.positions[base + v] =
                                            glm::vec3(transform.matrix * glm::dvec4(p[0], p[1], p[2], 1.0));
                                      });
        !e.empty()) {
      return error(part, where + "POSITION: " + e);
    }
    if (all_normals_) {
      out_.normals.resize(base + vertex_count);
      if (std::string e = read_accessor(model_, normal_accessor, 3, true, count,
                                        [&](std::size_t v, const float* n) {
                                          out_.normals[base + v] = glm::vec3(transform.normal_matrix *
                                                                             glm::dvec3(n[0], n[1], n[2]));
                                        });
          !e.empty()) {
        return error(part, where + "NORMAL: " + e);
      }
    } else {
      out_.normals.clear();
    }
    if (all_uvs_) {
      // glTF puts the UV origin at the top-left of the image; nmbake (like
      // OBJ, PLY and Blender) at the bottom-left: v' = 1 - v.
      out_.uvs.resize(base + vertex_count);
      if (std::string e = read_accessor(
              model_, uv_accessor, 2, false, count,
              [&](std::size_t v, const float* uv) { out_.uvs[base + v] = glm::vec2(uv[0], 1.0f - uv[1]); });
          !e.empty()) {
        return error(part, where + uv_key + ": " + e);
      }
    }
    if (all_tangents_) {
      // A tangent is a direction in the surface: it follows the linear part
      // of the matrix. A mirroring matrix flips the bitangent
      // w * cross(N, T) relative to the transformed frame, so w flips too.
      const glm::dmat3 linear(transform.matrix);
      out_.tangents.resize(base + vertex_count);
      if (std::string e = read_accessor(model_, tangent_accessor, 4, true, count,
                                        [&](std::size_t v, const float* t) {
                                          const float w = t[3] < 0.0f ? -1.0f : 1.0f;
                                          out_.tangents[base + v] =
                                              glm::vec4(glm::vec3(linear * glm::dvec3(t[0], t[1], t[2])),
                                                        transform.mirrored ? -w : w);
                                        });
          !e.empty()) {
        return error(part, where + "TANGENT: " + e);
      }
    } else {
      out_.tangents.clear();
    }
    if (options_.keep_colors) {
      // glTF colours are linear; nmbake's colours (as a PLY's bytes, and as
      // the vertex-color map writes them, with no curve) are sRGB-encoded:
      // RGB goes through the sRGB curve, alpha stays linear.
      out_.colors.resize(base + vertex_count, glm::vec4(1.0f));
      if (color_accessor >= 0) {
        any_colors_ = true;
        const auto encode = linear_to_srgb;
        if (std::string e = read_accessor(model_, color_accessor, color_components, false, count,
                                          [&](std::size_t v, const float* c) {
                                            out_.colors[base + v] =
                                                glm::vec4(encode(c[0]), encode(c[1]), encode(c[2]),
                                                          color_components == 4 ? c[3] : 1.0f);
                                          });
            !e.empty()) {
          return error(part, where + "COLOR_0: " + e);
        }
      }
    }

    // Corner UVs (LoadOptions::corner_uvs): the primitive's UV set, v
    // flipped as above; (0, 0) and counted when it has none.
    std::vector<glm::vec2> corner_source;
    if (options_.corner_uvs) {
      const int accessor = attribute(uv_key);
      if (accessor >= 0) {
        if (std::string e = check_count(accessor, uv_key); !e.empty()) return error(part, where + e);
        corner_source.resize(vertex_count);
        if (std::string e = read_accessor(
                model_, accessor, 2, false, count,
                [&](std::size_t v, const float* uv) { corner_source[v] = glm::vec2(uv[0], 1.0f - uv[1]); });
            !e.empty()) {
          return error(part, where + uv_key + ": " + e);
        }
      }
    }
    const auto emit = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
      // A mirroring matrix turns counter-clockwise into clockwise: swap two
      // corners so the front stays the front.
      if (transform.mirrored) std::swap(b, c);
      out_.indices.push_back(base + a);
      out_.indices.push_back(base + b);
      out_.indices.push_back(base + c);
      if (options_.corner_uvs) {
        for (const std::uint32_t v : {a, b, c}) {
          if (corner_source.empty()) ++stats_.corners_without_uvs;
          out_.corner_uvs.push_back(corner_source.empty() ? glm::vec2(0.0f) : corner_source[v]);
        }
      }
    };
    const std::size_t n = indices.size();
    if (mode == TINYGLTF_MODE_TRIANGLES) {
      if (n % 3 != 0) return error(part, where + std::to_string(n) + " indices is not a multiple of 3");
      for (std::size_t i = 0; i + 2 < n; i += 3) emit(indices[i], indices[i + 1], indices[i + 2]);
    } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
      // Every other triangle reversed, as the specification orders strips;
      // triangles with a repeated vertex only join strips: skipped, counted.
      for (std::size_t i = 0; i + 2 < n; ++i) {
        const std::uint32_t a = indices[i];
        const std::uint32_t b = indices[i + 1 + (i % 2)];
        const std::uint32_t c = indices[i + 2 - (i % 2)];
        if (a == b || b == c || a == c) {
          ++stats_.degenerate_faces;
          continue;
        }
        emit(a, b, c);
      }
    } else {
      // A fan around vertex 0, like the OBJ loader's polygons.
      for (std::size_t i = 1; i + 1 < n; ++i) emit(indices[0], indices[i], indices[i + 1]);
    }
    return Status::ok();
  }

  const std::string& path_;
  const tinygltf::Model& model_;
  const LoadOptions& options_;
  Mesh& out_;
  LoadStats& stats_;
  std::vector<int> mesh_users_;
  std::map<std::string, int> part_names_;
  std::size_t node_meshes_ = 0;
  bool all_normals_ = true;
  bool all_uvs_ = true;
  bool any_uvs_ = false;
  bool all_tangents_ = true;
  bool any_tangents_ = false;
  bool any_without_tangents_ = false;
  bool any_colors_ = false;
  std::map<std::size_t, int> embedded_;  // image index -> Mesh::embedded_images
};

// Geometry only: images are neither decoded nor, being external, read
// (TINYGLTF_NO_EXTERNAL_IMAGE); an embedded one is skipped unread, unless
// materials are read (keep_image_bytes).
bool skip_image(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int,
                void*) {
  return true;
}

// With material definitions, a data: URI image's bytes (decoded from base64
// by tinygltf) are kept, still compressed, in Image::image for
// texture_ref(); a buffer view's are taken from the buffer there, with its
// range checked (tinygltf hands over a pointer into the buffer unchecked).
bool keep_image_bytes(tinygltf::Image* image, const int, std::string*, std::string*, int, int,
                      const unsigned char* bytes, int size, void*) {
  if (image->bufferView < 0 && bytes != nullptr && size > 0) image->image.assign(bytes, bytes + size);
  return true;
}

// Whether the JSON of a file tinygltf refused names the Draco extension: the
// first 16 MiB (a .glb's JSON chunk comes first) are searched.
bool mentions_draco(const std::vector<unsigned char>& bytes) {
  const std::string_view head(reinterpret_cast<const char*>(bytes.data()),
                              std::min<std::size_t>(bytes.size(), std::size_t{16} << 20));
  return head.find("\"KHR_draco_mesh_compression\"") != std::string_view::npos;
}

// tinygltf's error text on one line and of a readable length: it quotes a
// data: URI it could not decode whole (a 200 MB file gave a 200 MB message).
std::string first_line(std::string text) {
  constexpr std::size_t kMaxMessageBytes = 400;
  if (text.size() > kMaxMessageBytes) text = text.substr(0, kMaxMessageBytes) + " [...]";
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.pop_back();
  std::replace(text.begin(), text.end(), '\n', ';');
  return text;
}

// ------------------------------------------------------------ buffer files
//
// A buffer's uri is a path relative to the glTF's folder, and tinygltf
// opens whatever it names: "../../etc/passwd", "/etc/passwd", the folder "."
// (a directory opened as a file: a size of 2^63, std::bad_alloc), a FIFO
// (blocks), and, when the folder has no such file, the same name in the
// working folder. nmbake reads a buffer only from a regular file under the
// glTF's folder: a relative path that does not leave it (checked on the
// path's text; a symbolic link inside the folder is followed, being the
// folder owner's choice, not the file's).

// tinygltf's decoding of a buffer uri (dlib's urldecode: %XX, '+' a space),
// so that the check sees the path tinygltf opens.
std::string decode_uri(const std::string& uri) {
  const auto hex = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return 0;  // as dlib's from_hex
  };
  std::string out;
  for (std::size_t i = 0; i < uri.size(); ++i) {
    if (uri[i] == '+') {
      out += ' ';
    } else if (uri[i] == '%' && uri.size() > i + 2) {
      out += static_cast<char>((hex(uri[i + 1]) << 4) | hex(uri[i + 2]));
      i += 2;
    } else {
      out += uri[i];
    }
  }
  return out;
}

// Empty when `relative` (a decoded uri) names a regular file under `folder`,
// else why it may not be read.
std::string buffer_file_problem(const std::string& folder, const std::string& relative) {
  namespace fs = std::filesystem;
  if (relative.empty()) return "the uri is empty";
  if (relative.find('\0') != std::string::npos) return "the uri holds a NUL byte";
  if (relative.front() == '/') {
    return "the uri is an absolute path (buffers are read only from files under the glTF's folder)";
  }
  // "a/../../x" leaves the folder as surely as "../x" does.
  const fs::path normal = fs::path(relative).lexically_normal();
  if (!normal.empty() && *normal.begin() == "..") {
    return "the uri leaves the glTF's folder (buffers are read only from files under it)";
  }
  struct stat st {};
  if (::stat((fs::path(folder) / normal).c_str(), &st) != 0) {
    return std::string("cannot open it: ") + std::strerror(errno);
  }
  if (S_ISDIR(st.st_mode)) return "the uri names a folder, not a file";
  if (!S_ISREG(st.st_mode)) return "the uri names no regular file (a FIFO, socket or device)";
  return {};
}

// tinygltf's file system (its FsCallbacks), confined to the glTF's folder.
struct BufferFiles {
  std::string folder;   // absolute; tinygltf joins it and the uri with a '/'
  std::string refused;  // the first uri refused and why, for the message
};

bool buffer_file_exists(const std::string& candidate, void* user) {
  BufferFiles& files = *static_cast<BufferFiles*>(user);
  const std::string prefix = files.folder.back() == '/' ? files.folder : files.folder + "/";
  // tinygltf tries the glTF's folder, then "./uri" (the working folder):
  // only the first is where a buffer may be.
  if (candidate.compare(0, prefix.size(), prefix) != 0) return false;
  const std::string relative = candidate.substr(prefix.size());
  const std::string problem = buffer_file_problem(files.folder, relative);
  if (problem.empty()) return true;
  if (files.refused.empty()) files.refused = "buffer uri '" + printable_text(relative) + "': " + problem;
  return false;
}

std::string keep_path(const std::string& path, void*) { return path; }  // no ~ or $VAR expansion

// Reads a whole buffer file; a FIFO or device put in the file's place after
// the check is refused by what was opened (O_NONBLOCK: opening a FIFO does
// not wait for a writer).
bool read_buffer_file(std::vector<unsigned char>* out, std::string* err, const std::string& path, void*) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) {
    *err = std::strerror(errno);
    return false;
  }
  struct stat st {};
  bool ok = ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode);
  if (!ok) *err = "not a regular file";
  const auto size = static_cast<std::uint64_t>(ok ? st.st_size : 0);
  if (const MemoryLimit limit = available_memory(); ok && limit.bytes != 0 && size > limit.bytes) {
    *err = "a " + memory_text(size) + " buffer; " + memory_text(limit.bytes) + " are available (" +
           limit.source + ")";
    ok = false;
  }
  if (ok) {
    out->resize(static_cast<std::size_t>(size));
    std::size_t done = 0;
    while (done < out->size()) {
      const ssize_t got = ::read(fd, out->data() + done, out->size() - done);
      if (got < 0 && errno == EINTR) continue;
      if (got <= 0) break;
      done += static_cast<std::size_t>(got);
    }
    out->resize(done);  // a file that shrank: tinygltf's byteLength check says so
  }
  ::close(fd);
  return ok;
}

bool write_nothing(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
  *err = "the loader writes no file";
  return false;
}

// ------------------------------------------------------------ JSON scan
//
// One pass over the JSON (nlohmann's SAX parser: nothing is kept but a
// little state) for what tinygltf reads lossily or not at all: it casts
// every index to int, so 2^40 becomes 0 (another mesh, silently) and 2^31 or
// any negative value means "none"; a float or a string is "none" too. An
// index here must be a whole number in [0, 2^31). The scan also checks the
// buffers' uris (above) before anything is read, naming the buffer, and the
// asset version (glTF 1.0 is another format).
class JsonScan : public nlohmann::json_sax<nlohmann::json> {
 public:
  explicit JsonScan(std::string folder) : folder_(std::move(folder)) {}
  const std::string& problem() const { return problem_; }

  bool null() override { return scalar("null", false); }
  bool boolean(bool value) override { return scalar(value ? "true" : "false", false); }
  bool number_integer(number_integer_t value) override {
    return scalar(std::to_string(value), value >= 0 && value <= kMaxIndex);
  }
  bool number_unsigned(number_unsigned_t value) override {
    return scalar(std::to_string(value), value <= static_cast<number_unsigned_t>(kMaxIndex));
  }
  bool number_float(number_float_t, const string_t& text) override { return scalar(text, false); }
  bool string(string_t& value) override {
    if (skipping()) return true;
    const std::size_t depth = frames_.size();
    if (depth == 2 && top_key() == "asset" && frames_[1].key == "version" && value.rfind("2.", 0) != 0) {
      return fail("asset version '" + printable_text(value) + "': only glTF 2.0 is read");
    }
    if (depth == 3 && top_key() == "buffers" && frames_[2].key == "uri" && value.rfind("data:", 0) != 0) {
      if (std::string p = buffer_file_problem(folder_, decode_uri(value)); !p.empty()) {
        return fail("buffer " + std::to_string(frames_[1].items - 1) + " (uri '" + printable_text(value) +
                    "'): " + p);
      }
    }
    return scalar("a string", false);
  }
  bool binary(binary_t&) override { return true; }
  bool start_object(std::size_t) override { return open(false); }
  bool end_object() override { return close(); }
  bool start_array(std::size_t) override { return open(true); }
  bool end_array() override { return close(); }
  bool key(string_t& name) override {
    frames_.back().key = name;
    return true;
  }
  // A syntax error is tinygltf's to report, in its words.
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) override {
    return false;
  }

 private:
  static constexpr std::int64_t kMaxIndex = 0x7fffffff;

  struct Frame {
    bool array = false;
    std::string key;        // objects: the current key
    std::size_t items = 0;  // arrays: elements opened so far
  };

  const std::string& top_key() const { return frames_[0].key; }
  // Inside "extensions" or "extras": anything goes.
  bool skipping() const { return skip_depth_ != 0 && frames_.size() >= skip_depth_; }

  bool open(bool array) {
    if (!frames_.empty() && frames_.back().array) ++frames_.back().items;
    if (!skipping() && !frames_.empty() && !frames_.back().array &&
        (frames_.back().key == "extensions" || frames_.back().key == "extras")) {
      skip_depth_ = frames_.size() + 1;
    }
    frames_.push_back(Frame{array, {}, 0});
    return true;
  }
  bool close() {
    frames_.pop_back();
    if (skip_depth_ != 0 && frames_.size() < skip_depth_) skip_depth_ = 0;
    return true;
  }
  bool fail(const std::string& problem) {
    problem_ = problem;
    return false;  // stops the parse
  }

  // The key a value is under: its object's key, or, in an array, the key of
  // the object holding the array ("children": [1, 2]).
  const std::string* field() const {
    for (auto it = frames_.rbegin(); it != frames_.rend(); ++it) {
      if (!it->array) return &it->key;
    }
    return nullptr;
  }

  // Where a value is, for the message: "node 3: mesh", "mesh 0: primitives[0].indices".
  std::string location() const {
    static const std::map<std::string, std::string> kSingular = {
        {"nodes", "node"},         {"meshes", "mesh"},
        {"accessors", "accessor"}, {"bufferViews", "buffer view"},
        {"buffers", "buffer"},     {"scenes", "scene"},
        {"materials", "material"}, {"textures", "texture"},
        {"skins", "skin"},         {"animations", "animation"}};
    std::string text;
    for (std::size_t d = 0; d < frames_.size(); ++d) {
      const Frame& f = frames_[d];
      if (f.array) {
        // The element being read is the last one opened.
        const std::string index = std::to_string(f.items == 0 ? 0 : f.items - 1);
        if (d == 1 && kSingular.count(frames_[0].key) != 0) {
          text = kSingular.at(frames_[0].key) + " " + index;
        } else {
          text += "[" + index + "]";
        }
      } else if (d + 1 < frames_.size() || !f.key.empty()) {
        if (d == 0) {
          text = f.key;
        } else {
          text += (d == 2 && frames_[1].array && kSingular.count(frames_[0].key) != 0 ? ": " : ".") + f.key;
        }
      }
    }
    return text;
  }

  bool scalar(const std::string& text, bool is_index) {
    if (frames_.empty() || skipping()) return true;
    if (frames_.back().array) ++frames_.back().items;
    const std::string* key = field();
    if (key == nullptr) return true;
    // The keys tinygltf reads as an int index (glTF 2.0's "glTFid"s), and
    // the attribute maps, whose values are accessor indices.
    static const char* const kIndexKeys[] = {"scene",
                                             "nodes",
                                             "children",
                                             "mesh",
                                             "skin",
                                             "camera",
                                             "indices",
                                             "material",
                                             "bufferView",
                                             "buffer",
                                             "sampler",
                                             "source",
                                             "index",
                                             "node",
                                             "joints",
                                             "skeleton",
                                             "inverseBindMatrices",
                                             "input",
                                             "output"};
    bool index_field = std::find(std::begin(kIndexKeys), std::end(kIndexKeys), *key) != std::end(kIndexKeys);
    if (!frames_.back().array && frames_.size() >= 2) {
      const Frame& holder = frames_[frames_.size() - 2];
      if (!holder.array && holder.key == "attributes") index_field = true;
    }
    // Top-level "nodes" holds objects; a scalar there is tinygltf's to refuse.
    if (!index_field || is_index || (frames_.size() == 2 && frames_[1].array)) return true;
    const std::string what = location();
    return fail(what + " is " + printable_text(text) +
                ", not an index (a whole number from 0 to 2147483647)");
  }

  std::string folder_;
  std::vector<Frame> frames_;
  std::size_t skip_depth_ = 0;
  std::string problem_;
};

}  // namespace

Status load_gltf(const std::string& path, const LoadOptions& options, Mesh& out, LoadStats& stats) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    return Status::bad_input(
        path + ": cannot open: " + (fs::exists(path, ec) ? "not a regular file" : "no such file"));
  }
  const bool binary = lower_extension(path) == ".glb";
  const std::uint64_t file_bytes = fs::file_size(path, ec);
  if (ec) return Status::bad_input(path + ": cannot open: " + ec.message());
  // tinygltf takes the file's length as 32 bits (and a .glb's header says
  // it in 32 bits).
  if (file_bytes > 0xffffffffu) {
    return Status::bad_input(path + ": larger than 4 GiB, the most a glTF file can be read");
  }
  // tinygltf holds the file, its JSON document (a data: URI's text a second
  // time, and a third while it is lexed) and the decoded buffers at once:
  // a 200 MB .gltf of data: URIs peaked at 1.3 GB. Refused up front when that
  // cannot fit, rather than dying in std::bad_alloc halfway.
  const std::uint64_t parse_bytes = file_bytes * (binary ? kGlbParseBytesPerByte : kGltfParseBytesPerByte);
  if (const MemoryLimit limit = available_memory(); limit.bytes != 0 && parse_bytes > limit.bytes) {
    return Status::bad_input(path + ": reading this " + memory_text(file_bytes) + " glTF file takes about " +
                             memory_text(parse_bytes) + " (its JSON, data: URIs and buffers at once); " +
                             memory_text(limit.bytes) + " are available (" + limit.source + ")");
  }
  std::vector<unsigned char> bytes;
  std::string read_error;
  if (!read_buffer_file(&bytes, &read_error, path, nullptr)) {
    return Status::bad_input(path + ": cannot read: " + read_error);
  }
  if (bytes.empty()) return Status::bad_input(path + ": the file is empty");

  // The JSON: the whole .gltf, or a .glb's first chunk (tinygltf checks the
  // chunk layout; the version it does not: a GLB 1 file is glTF 1.0).
  std::string_view json(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  if (binary && bytes.size() >= 20 && json.substr(0, 4) == "glTF") {
    std::uint32_t version = 0;
    std::uint32_t json_bytes = 0;
    std::memcpy(&version, bytes.data() + 4, 4);
    std::memcpy(&json_bytes, bytes.data() + 12, 4);
    if (version != 2) {
      return Status::bad_input(path + ": GLB version " + std::to_string(version) +
                               ": only version 2 (glTF 2.0) is read");
    }
    json = json.substr(20, std::min<std::size_t>(json_bytes, bytes.size() - 20));
  }
  BufferFiles buffer_files{fs::absolute(path, ec).parent_path().lexically_normal().string(), {}};
  if (ec || buffer_files.folder.empty())
    return Status::bad_input(path + ": cannot find its folder: " + ec.message());
  JsonScan scan(buffer_files.folder);
  nlohmann::json::sax_parse(json, &scan);
  if (!scan.problem().empty()) return Status::bad_input(path + ": " + scan.problem());

  tinygltf::TinyGLTF parser;
  parser.SetImageLoader(options.material_defs ? keep_image_bytes : skip_image, nullptr);
  parser.SetFsCallbacks(
      tinygltf::FsCallbacks{buffer_file_exists, keep_path, read_buffer_file, write_nothing, &buffer_files});
  tinygltf::Model model;
  std::string error_text;
  std::string warning_text;
  const auto size = static_cast<unsigned int>(bytes.size());
  const auto* text = reinterpret_cast<const char*>(bytes.data());
  bool loaded = false;
  try {
    loaded = binary ? parser.LoadBinaryFromMemory(&model, &error_text, &warning_text, bytes.data(), size,
                                                  buffer_files.folder)
                    : parser.LoadASCIIFromString(&model, &error_text, &warning_text, text, size,
                                                 buffer_files.folder);
  } catch (const std::exception& e) {
    // tinygltf throws on some broken files (a GLB buffer of byteLength 0:
    // std::out_of_range from vector::at, found by fuzz_gltf): the file's
    // fault, not ours.
    return Status::bad_input(path + ": glTF: the file is broken (tinygltf: " + first_line(e.what()) + ")");
  }
  if (!loaded) {
    if (!buffer_files.refused.empty()) return Status::bad_input(path + ": " + buffer_files.refused);
    if (error_text.empty()) error_text = "cannot be read as glTF";
    // tinygltf (built without Draco) stops at a Draco file's accessors,
    // which have no buffer view; say what the file really is.
    if (mentions_draco(bytes)) {
      return Status::bad_input(
          path + ": the file uses KHR_draco_mesh_compression: Draco-compressed meshes are not supported");
    }
    return Status::bad_input(path + ": glTF: " + first_line(error_text));
  }
  bytes = {};               // the model holds what it needs
  stats.unit_meters = 1.0;  // glTF positions are metres by definition
  stats.bytes = file_bytes;
  for (const tinygltf::Buffer& buffer : model.buffers) {
    // External buffers count into the bytes read; a .glb's own and data:
    // URIs are inside the file already.
    if (!buffer.uri.empty() && buffer.uri.rfind("data:", 0) != 0) {
      stats.bytes += buffer.data.size();
      stats.files.push_back((std::filesystem::path(path).parent_path() / buffer.uri).string());
    }
  }
  GltfReader reader(path, model, options, out, stats);
  return reader.read();
}

}  // namespace nmbake::load_detail

namespace nmbake {

// NMBAKE_TINYGLTF_VERSION: the first version in tiny_gltf.h's change log,
// read by CMake (tinygltf has no version macro).
std::string tinygltf_version() { return NMBAKE_TINYGLTF_VERSION; }

}  // namespace nmbake
