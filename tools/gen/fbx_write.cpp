// Binary FBX 7.4 as the format is publicly described (Blender's developer
// notes on "FBX binary file format specification"): a 27-byte header, then
// node records {uint32 end offset, uint32 property count, uint32 property
// bytes, uint8 name length, name, properties, nested records, 13 zero bytes
// closing a nested list}, ending with a null record.
#include "fbx_write.hpp"

#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>

namespace nmbake::gen {

namespace {

class FbxWriter {
 public:
  // A node: `properties` writes its properties (counted by the helpers
  // below), `children` its nested nodes (may be empty).
  void node(const std::string& name, const std::function<void()>& properties,
            const std::function<void()>& children = {}) {
    const std::size_t start = out_.size();
    put<std::uint32_t>(0);  // end offset, patched below
    put<std::uint32_t>(0);  // property count, patched
    put<std::uint32_t>(0);  // property bytes, patched
    out_.push_back(static_cast<char>(name.size()));
    out_ += name;
    const std::size_t property_start = out_.size();
    const std::uint32_t saved_count = property_count_;
    property_count_ = 0;
    if (properties) properties();
    patch(start + 4, property_count_);
    patch(start + 8, static_cast<std::uint32_t>(out_.size() - property_start));
    property_count_ = saved_count;
    if (children) {
      children();
      out_.append(13, '\0');
    }
    patch(start, static_cast<std::uint32_t>(out_.size()));
  }

  void i32(std::int32_t v) { typed('I', v); }
  void i64(std::int64_t v) { typed('L', v); }
  void f64(double v) { typed('D', v); }
  void str(const std::string& s) {
    ++property_count_;
    out_.push_back('S');
    put<std::uint32_t>(static_cast<std::uint32_t>(s.size()));
    out_ += s;
  }
  void raw(const std::string& s) {
    ++property_count_;
    out_.push_back('R');
    put<std::uint32_t>(static_cast<std::uint32_t>(s.size()));
    out_ += s;
  }
  void f64_array(const std::vector<double>& values) { array('d', values); }
  void i32_array(const std::vector<std::int32_t>& values) { array('i', values); }

  std::string& bytes() { return out_; }

 private:
  template <typename T>
  void put(T v) {
    char raw[sizeof(T)];
    std::memcpy(raw, &v, sizeof(T));  // FBX is little endian, like the machines we run on
    out_.append(raw, sizeof(T));
  }
  template <typename T>
  void typed(char code, T v) {
    ++property_count_;
    out_.push_back(code);
    put(v);
  }
  template <typename T>
  void array(char code, const std::vector<T>& values) {
    ++property_count_;
    out_.push_back(code);
    put<std::uint32_t>(static_cast<std::uint32_t>(values.size()));
    put<std::uint32_t>(0);  // encoding: raw, not deflated
    put<std::uint32_t>(static_cast<std::uint32_t>(values.size() * sizeof(T)));
    out_.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
  }
  void patch(std::size_t at, std::uint32_t v) { std::memcpy(out_.data() + at, &v, 4); }

  std::string out_;
  std::uint32_t property_count_ = 0;
};

// P: "name", "type", "label", "flags", values...: one Properties70 entry.
void vector_property(FbxWriter& w, const std::string& name, const glm::dvec3& v) {
  w.node("P", [&] {
    w.str(name);
    w.str(name);
    w.str("");
    w.str("A");
    w.f64(v.x);
    w.f64(v.y);
    w.f64(v.z);
  });
}

}  // namespace

Status write_fbx_binary(const std::string& path, const Mesh& mesh, const FbxModel& model,
                        const std::vector<std::uint32_t>& polygon_sizes) {
  if (mesh.indices.size() > 0x7fffffffu || mesh.vertex_count() > 0x7fffffffu) {
    return Status::bad_input(path + ": too large for 32-bit FBX offsets");
  }
  FbxWriter w;
  std::string& out = w.bytes();
  out.append("Kaydara FBX Binary  ", 20);
  out.push_back('\0');
  out.push_back('\x1a');
  out.push_back('\0');
  const std::uint32_t version = 7400;
  out.append(reinterpret_cast<const char*>(&version), 4);

  w.node("FBXHeaderExtension", {}, [&] {
    w.node("FBXHeaderVersion", [&] { w.i32(1003); });
    w.node("FBXVersion", [&] { w.i32(7400); });
  });
  w.node("GlobalSettings", {}, [&] {
    w.node("Version", [&] { w.i32(1000); });
    w.node("Properties70", {}, [&] {
      w.node("P", [&] {
        w.str("UnitScaleFactor");
        w.str("double");
        w.str("Number");
        w.str("");
        w.f64(model.unit_scale_factor);
      });
    });
  });

  constexpr std::int64_t kGeometryId = 1000;
  constexpr std::int64_t kModelId = 2000;
  constexpr std::int64_t kMaterialId = 3000;
  constexpr std::int64_t kTextureId = 4000;
  constexpr std::int64_t kVideoId = 5000;
  std::vector<double> vertices;
  vertices.reserve(mesh.vertex_count() * 3);
  for (const glm::vec3& p : mesh.positions) vertices.insert(vertices.end(), {p.x, p.y, p.z});
  // Polygon corners; the last corner of each polygon is stored as -(i + 1).
  std::vector<std::int32_t> corners(mesh.indices.begin(), mesh.indices.end());
  if (polygon_sizes.empty()) {
    for (std::size_t c = 2; c < corners.size(); c += 3) corners[c] = -corners[c] - 1;
  } else {
    std::size_t end = 0;
    for (const std::uint32_t size : polygon_sizes) {
      end += size;
      corners[end - 1] = -corners[end - 1] - 1;
    }
  }
  w.node("Objects", {}, [&] {
    w.node(
        "Geometry",
        [&] {
          w.i64(kGeometryId);
          w.str(model.name + std::string("\0\1Geometry", 10));
          w.str("Mesh");
        },
        [&] {
          w.node("Vertices", [&] { w.f64_array(vertices); });
          w.node("PolygonVertexIndex", [&] { w.i32_array(corners); });
          w.node("GeometryVersion", [&] { w.i32(124); });
          if (mesh.has_normals()) {
            w.node(
                "LayerElementNormal", [&] { w.i32(0); },
                [&] {
                  w.node("Version", [&] { w.i32(101); });
                  w.node("Name", [&] { w.str(""); });
                  w.node("MappingInformationType", [&] { w.str("ByVertice"); });
                  w.node("ReferenceInformationType", [&] { w.str("Direct"); });
                  std::vector<double> normals;
                  normals.reserve(mesh.vertex_count() * 3);
                  for (const glm::vec3& n : mesh.normals) normals.insert(normals.end(), {n.x, n.y, n.z});
                  w.node("Normals", [&] { w.f64_array(normals); });
                });
          }
          if (mesh.has_uvs()) {
            w.node(
                "LayerElementUV", [&] { w.i32(0); },
                [&] {
                  w.node("Version", [&] { w.i32(101); });
                  w.node("Name", [&] { w.str("UVMap"); });
                  w.node("MappingInformationType", [&] { w.str("ByVertice"); });
                  w.node("ReferenceInformationType", [&] { w.str("Direct"); });
                  std::vector<double> uvs;
                  uvs.reserve(mesh.vertex_count() * 2);
                  for (const glm::vec2& uv : mesh.uvs) uvs.insert(uvs.end(), {uv.x, uv.y});
                  w.node("UV", [&] { w.f64_array(uvs); });
                });
          }
          if (!model.material.empty()) {
            w.node(
                "LayerElementMaterial", [&] { w.i32(0); },
                [&] {
                  w.node("Version", [&] { w.i32(101); });
                  w.node("Name", [&] { w.str(""); });
                  w.node("MappingInformationType", [&] { w.str("AllSame"); });
                  w.node("ReferenceInformationType", [&] { w.str("IndexToDirect"); });
                  w.node("Materials", [&] { w.i32_array({0}); });
                });
          }
          w.node(
              "Layer", [&] { w.i32(0); },
              [&] {
                w.node("Version", [&] { w.i32(100); });
                if (!model.material.empty()) {
                  w.node("LayerElement", {}, [&] {
                    w.node("Type", [&] { w.str("LayerElementMaterial"); });
                    w.node("TypedIndex", [&] { w.i32(0); });
                  });
                }
                if (mesh.has_normals()) {
                  w.node("LayerElement", {}, [&] {
                    w.node("Type", [&] { w.str("LayerElementNormal"); });
                    w.node("TypedIndex", [&] { w.i32(0); });
                  });
                }
                if (mesh.has_uvs()) {
                  w.node("LayerElement", {}, [&] {
                    w.node("Type", [&] { w.str("LayerElementUV"); });
                    w.node("TypedIndex", [&] { w.i32(0); });
                  });
                }
              });
        });
    w.node(
        "Model",
        [&] {
          w.i64(kModelId);
          w.str(model.name + std::string("\0\1Model", 7));
          w.str("Mesh");
        },
        [&] {
          w.node("Version", [&] { w.i32(232); });
          w.node("Properties70", {}, [&] {
            vector_property(w, "Lcl Translation", model.translation);
            vector_property(w, "Lcl Rotation", model.rotation_degrees);
            vector_property(w, "Lcl Scaling", model.scaling);
          });
        });
    if (!model.material.empty()) {
      w.node(
          "Material",
          [&] {
            w.i64(kMaterialId);
            w.str(model.material + std::string("\0\1Material", 10));
            w.str("");
          },
          [&] {
            w.node("Version", [&] { w.i32(102); });
            w.node("ShadingModel", [&] { w.str("lambert"); });
            w.node("Properties70", {}, [&] {
              w.node("P", [&] {
                w.str("DiffuseColor");
                w.str("Color");
                w.str("");
                w.str("A");
                w.f64(model.diffuse.x);
                w.f64(model.diffuse.y);
                w.f64(model.diffuse.z);
              });
            });
          });
    }
    if (!model.material.empty() && !model.texture.empty()) {
      w.node(
          "Texture",
          [&] {
            w.i64(kTextureId);
            w.str(std::string("diffuse\0\1Texture", 16));
            w.str("");
          },
          [&] {
            w.node("Type", [&] { w.str("TextureVideoClip"); });
            w.node("Version", [&] { w.i32(202); });
            w.node("TextureName", [&] { w.str(std::string("diffuse\0\1Texture", 16)); });
            w.node("FileName", [&] { w.str(model.texture); });
            w.node("RelativeFilename", [&] { w.str(model.texture); });
          });
      if (!model.embedded.empty()) {
        w.node(
            "Video",
            [&] {
              w.i64(kVideoId);
              w.str(std::string("diffuse\0\1Video", 14));
              w.str("Clip");
            },
            [&] {
              w.node("Type", [&] { w.str("Clip"); });
              w.node("FileName", [&] { w.str(model.texture); });
              w.node("RelativeFilename", [&] { w.str(model.texture); });
              w.node("Content", [&] { w.raw(model.embedded); });
            });
      }
    }
  });
  w.node("Connections", {}, [&] {
    w.node("C", [&] {
      w.str("OO");
      w.i64(kGeometryId);
      w.i64(kModelId);
    });
    w.node("C", [&] {
      w.str("OO");
      w.i64(kModelId);
      w.i64(0);
    });
    if (!model.material.empty()) {
      w.node("C", [&] {
        w.str("OO");
        w.i64(kMaterialId);
        w.i64(kModelId);
      });
    }
    if (!model.material.empty() && !model.texture.empty()) {
      w.node("C", [&] {
        w.str("OP");
        w.i64(kTextureId);
        w.i64(kMaterialId);
        w.str("DiffuseColor");
      });
      if (!model.embedded.empty()) {
        w.node("C", [&] {
          w.str("OO");
          w.i64(kVideoId);
          w.i64(kTextureId);
        });
      }
    }
  });
  out.append(13, '\0');  // the null record that ends the top level

  const std::string temp = path + ".tmp";
  {
    std::ofstream file(temp, std::ios::binary | std::ios::trunc);
    file.write(out.data(), static_cast<std::streamsize>(out.size()));
    if (!file.good()) return Status::io(path + ": cannot write");
  }
  std::error_code ec;
  std::filesystem::rename(temp, path, ec);
  if (ec) return Status::io(path + ": cannot write: " + ec.message());
  return Status::ok();
}

}  // namespace nmbake::gen
