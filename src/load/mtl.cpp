// Wavefront MTL reader (the material library an OBJ names with `mtllib`):
// the statements of the Wavefront Advanced Visualizer manual, appendix B1
// "Material Library File (.mtl)" a bake reads, plus the PBR extension that
// Blender, 3ds Max and the tinyobjloader family write (Pr, Pm, Ke, norm).
//
//   newmtl NAME           a material (the rest of the line, blanks trimmed)
//   Kd r g b              base colour (linear, as Blender and three.js read it)
//   d v / Tr v            opacity (Tr = 1 - d; d wins when both are given)
//   Ke r g b              emission
//   Pr v / Pm v           roughness, metallic
//   map_Kd, map_d, map_Ke, map_Pr, map_Pm     their textures
//   norm, map_Bump, bump  a tangent-space normal texture (-bm: its scale);
//                         Blender writes its normal maps as map_Bump
//
// Texture options: -o u [v [w]] and -s u [v [w]] (offset and scale of the
// UVs), -clamp on|off, -imfchan r|g|b|m|l|z (the channel a scalar reads; m
// and z read as alpha, l as luminance), -bm s; -blendu -blendv -cc -boost
// -mm -texres -t are read and ignored. The file name is the rest of the
// line (it may hold blanks); backslashes are folder separators (Windows
// exports). It is resolved against the MTL's folder; a path that does not
// exist there (an absolute path from another machine) is looked for by its
// file name beside the MTL, as other importers do. Textures are not opened
// here: only a bake that needs one does (maps/textures.cpp).
#include <algorithm>
#include <cstring>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "load/parsers.hpp"

namespace nmbake::load_detail {
namespace {

namespace fs = std::filesystem;

std::string trimmed(const char* p, const char* end) {
  p = skip_blanks(p, end);
  while (end > p && is_blank(end[-1])) --end;
  return std::string(p, end);
}

class MtlParser {
 public:
  MtlParser(const std::string& path, const std::vector<std::string>& used, std::vector<Material>& defs)
      : path_(path), folder_(fs::path(path).parent_path()), used_(used), defs_(defs) {}

  Status run(FileReader& reader) {
    std::string_view line;
    while (reader.next_line(line)) {
      line_ = reader.line_number();
      NMBAKE_TRY(parse_line(line));
    }
    NMBAKE_TRY(Status(reader.read_status()));
    flush();
    return Status::ok();
  }

 private:
  Status error(const std::string& reason) const { return text_error(path_, line_, reason); }

  Status parse_line(std::string_view text) {
    const char* p = skip_blanks(text.data(), text.data() + text.size());
    const char* end = text.data() + text.size();
    if (const void* hash = std::memchr(p, '#', static_cast<std::size_t>(end - p))) {
      end = static_cast<const char*>(hash);
    }
    if (p == end) return Status::ok();
    const char* keyword_end = skip_token(p, end);
    const std::string keyword(p, keyword_end);
    if (keyword == "newmtl") {
      flush();
      current_ = Material{};
      current_.name = trimmed(keyword_end, end);
      have_current_ = true;
      d_given_ = false;
      return Status::ok();
    }
    if (!have_current_) return Status::ok();  // statements before the first newmtl describe nothing
    if (keyword == "Kd") {
      glm::vec3 c;
      NMBAKE_TRY(reals(keyword_end, end, &c.x, 3));
      current_.base_color = glm::vec4(c, current_.base_color.a);
      current_.has_color = true;
    } else if (keyword == "d") {
      NMBAKE_TRY(reals(keyword_end, end, &current_.base_color.a, 1));
      d_given_ = true;
    } else if (keyword == "Tr") {
      float tr = 0.0f;
      NMBAKE_TRY(reals(keyword_end, end, &tr, 1));
      if (!d_given_) current_.base_color.a = 1.0f - tr;
    } else if (keyword == "Ke") {
      NMBAKE_TRY(reals(keyword_end, end, &current_.emissive.x, 3));
    } else if (keyword == "Pr") {
      NMBAKE_TRY(reals(keyword_end, end, &current_.roughness, 1));
    } else if (keyword == "Pm") {
      NMBAKE_TRY(reals(keyword_end, end, &current_.metallic, 1));
    } else if (keyword == "map_Kd") {
      NMBAKE_TRY(texture(keyword_end, end, current_.base_color_texture, nullptr));
    } else if (keyword == "map_d") {
      current_.opacity_texture.channel = 3;  // alpha, or the luminance of an image without one
      NMBAKE_TRY(texture(keyword_end, end, current_.opacity_texture, nullptr));
    } else if (keyword == "map_Ke") {
      NMBAKE_TRY(texture(keyword_end, end, current_.emissive_texture, nullptr));
    } else if (keyword == "map_Pr") {
      NMBAKE_TRY(texture(keyword_end, end, current_.roughness_texture, nullptr));
    } else if (keyword == "map_Pm") {
      NMBAKE_TRY(texture(keyword_end, end, current_.metallic_texture, nullptr));
    } else if (keyword == "norm" || keyword == "map_Bump" || keyword == "map_bump" || keyword == "bump") {
      NMBAKE_TRY(texture(keyword_end, end, current_.normal_texture, &current_.normal_scale));
    }
    return Status::ok();
  }

  // `count` reals; for Kd/Ke a single value means grey (the manual allows "Kd r").
  Status reals(const char* p, const char* end, float* out, int count) {
    int read = 0;
    for (; read < count; ++read) {
      p = skip_blanks(p, end);
      if (p == end) break;
      const char* token_end = skip_token(p, end);
      const NumberError e = parse_float(p, token_end, out[read]);
      if (e != NumberError::none)
        return error(number_error_text(e, std::string_view(p, static_cast<std::size_t>(token_end - p))));
      p = token_end;
    }
    if (read == 0) return error("expected a number");
    if (read == 1 && count == 3) out[1] = out[2] = out[0];
    if (read != 1 && read != count) return error("expected " + std::to_string(count) + " numbers");
    return Status::ok();
  }

  // Options, then the file name (the rest of the line).
  Status texture(const char* p, const char* end, TextureRef& ref, float* bump_scale) {
    const auto next = [&](std::string_view& token) {
      p = skip_blanks(p, end);
      const char* token_end = skip_token(p, end);
      token = std::string_view(p, static_cast<std::size_t>(token_end - p));
      return token_end;
    };
    // Up to `most` numbers after an option (at least one).
    const auto numbers = [&](float* values, int most) -> Status {
      int read = 0;
      for (; read < most; ++read) {
        std::string_view token;
        const char* after = next(token);
        float v = 0.0f;
        if (token.empty() || parse_float(token.data(), token.data() + token.size(), v) != NumberError::none)
          break;
        values[read] = v;
        p = after;
      }
      if (read == 0) return error("a texture option without its number");
      if (read == 1 && most >= 2) values[1] = values[0];
      return Status::ok();
    };
    glm::vec2 mtl_offset(0.0f);
    for (;;) {
      std::string_view token;
      const char* after = next(token);
      if (token.size() < 2 || token[0] != '-') break;
      if (token[1] >= '0' && token[1] <= '9') break;  // a file named "-1.png"
      p = after;
      const std::string option(token);
      if (option == "-o" || option == "-s") {
        float v[3] = {0.0f, 0.0f, 0.0f};
        NMBAKE_TRY(numbers(v, 3));
        if (option == "-o")
          mtl_offset = glm::vec2(v[0], v[1]);
        else
          ref.scale = glm::vec2(v[0], v[1]);
      } else if (option == "-t") {
        float v[3];
        NMBAKE_TRY(numbers(v, 3));
      } else if (option == "-bm" || option == "-boost" || option == "-texres") {
        float v = 1.0f;
        NMBAKE_TRY(numbers(&v, 1));
        if (option == "-bm" && bump_scale != nullptr) *bump_scale = v;
      } else if (option == "-mm") {
        float v[2];
        NMBAKE_TRY(numbers(v, 2));
      } else if (option == "-clamp" || option == "-blendu" || option == "-blendv" || option == "-cc") {
        std::string_view value;
        p = next(value);
        if (value != "on" && value != "off") return error(option + " takes on or off");
        if (option == "-clamp") {
          const TextureWrap wrap = value == "on" ? TextureWrap::clamp : TextureWrap::repeat;
          ref.wrap_u = ref.wrap_v = wrap;
        }
      } else if (option == "-imfchan") {
        std::string_view value;
        p = next(value);
        if (value == "r")
          ref.channel = 0;
        else if (value == "g")
          ref.channel = 1;
        else if (value == "b")
          ref.channel = 2;
        else if (value == "m" || value == "z")
          ref.channel = 3;
        else if (value == "l")
          ref.channel = -1;
        else
          return error("-imfchan takes r, g, b, m, l or z");
      } else {
        return error("unknown texture option '" + token_text(option) + "'");
      }
    }
    // -o and -s act on UVs with v up (u' = o + s u); TextureRef's transform
    // acts in the image's top-left convention: y' = (1 - o_v - s_v) + s_v y.
    ref.offset = glm::vec2(mtl_offset.x, 1.0f - mtl_offset.y - ref.scale.y);
    std::string name = trimmed(p, end);
    if (name.empty()) return error("a texture statement without a file name");
    std::replace(name.begin(), name.end(), '\\', '/');
    ref.path = resolve(name);
    return Status::ok();
  }

  std::string resolve(const std::string& name) const {
    const fs::path given(name);
    const fs::path beside = given.is_absolute() ? given : folder_ / given;
    std::error_code ec;
    if (fs::exists(beside, ec) || name.find("<UDIM>") != std::string::npos) return beside.string();
    const fs::path by_name = folder_ / given.filename();
    if (given.has_parent_path() && fs::exists(by_name, ec)) return by_name.string();
    return beside.string();  // missing: the bake that needs it says so
  }

  void flush() {
    if (!have_current_) return;
    have_current_ = false;
    // A map replaces its factor (Blender's importer: Blender's exporter
    // writes Kd 0.8 beside a map_Kd; the manual's product would darken it).
    if (!current_.base_color_texture.empty()) {
      current_.base_color = glm::vec4(1.0f, 1.0f, 1.0f, current_.base_color.a);
    }
    if (!current_.opacity_texture.empty()) current_.base_color.a = 1.0f;
    if (!current_.emissive_texture.empty()) current_.emissive = glm::vec3(1.0f);
    if (!current_.roughness_texture.empty()) current_.roughness = 1.0f;
    if (!current_.metallic_texture.empty()) current_.metallic = 1.0f;
    if (std::find(used_.begin(), used_.end(), current_.name) == used_.end()) return;
    const bool known =
        std::any_of(defs_.begin(), defs_.end(), [&](const Material& m) { return m.name == current_.name; });
    if (!known) defs_.push_back(current_);
  }

  const std::string& path_;
  fs::path folder_;
  const std::vector<std::string>& used_;
  std::vector<Material>& defs_;
  Material current_;
  bool have_current_ = false;
  bool d_given_ = false;
  std::uint64_t line_ = 0;
};

}  // namespace

Status read_mtl_library(const std::string& obj_path, const std::string& statement,
                        const std::vector<std::string>& used, std::vector<Material>& defs,
                        std::vector<std::string>& read_files) {
  const fs::path folder = fs::path(obj_path).parent_path();
  std::string name = statement;
  std::replace(name.begin(), name.end(), '\\', '/');
  // One file name with blanks, or several names (the manual allows a list).
  std::vector<std::string> files{name};
  std::error_code ec;
  if (!fs::exists(folder / name, ec) && name.find_first_of(" \t") != std::string::npos) {
    files.clear();
    const char* p = name.data();
    const char* end = p + name.size();
    for (p = skip_blanks(p, end); p < end; p = skip_blanks(p, end)) {
      const char* token_end = skip_token(p, end);
      files.emplace_back(p, token_end);
      p = token_end;
    }
  }
  for (const std::string& file : files) {
    const std::string path = (fs::path(file).is_absolute() ? fs::path(file) : folder / file).string();
    read_files.push_back(path);
    // A FIFO would block and a device never end: regular files only.
    const fs::file_status status = fs::status(path, ec);
    if (!fs::is_regular_file(status)) {
      return Status::bad_input(obj_path + ": mtllib '" + printable_text(file) +
                               "': " + (fs::exists(status) ? "not a regular file" : "no such file") +
                               " (looked for " + printable_text(path) + ")");
    }
    FileReader reader;
    if (Status s = reader.open(path); !s.is_ok()) {
      return Status::bad_input(obj_path + ": mtllib '" + printable_text(file) + "': " + s.message());
    }
    MtlParser parser(path, used, defs);
    NMBAKE_TRY(parser.run(reader));
  }
  return Status::ok();
}

}  // namespace nmbake::load_detail
