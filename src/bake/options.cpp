// The option table (options.hpp): each option's parser, once, for the
// command line, job files and live requests.
#include "nmbake/options.hpp"

#include <charconv>
#include <cmath>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>

#include "nmbake/memory.hpp"
#include "nmbake/preset.hpp"

namespace nmbake {

OptionValue OptionValue::of_text(std::string text) {
  OptionValue v;
  v.text = std::move(text);
  return v;
}

namespace {

// The value readers: each accepts what its type can arrive as (a job file's
// typed value, or a word of the command line).

bool read_int(const OptionValue& v, int& out) {
  if (v.kind == OptionValue::Kind::integer) {
    if (v.integer < std::numeric_limits<int>::min() || v.integer > std::numeric_limits<int>::max())
      return false;
    out = static_cast<int>(v.integer);
    return true;
  }
  if (v.kind != OptionValue::Kind::text) return false;
  const char* end = v.text.data() + v.text.size();
  const auto r = std::from_chars(v.text.data(), end, out);
  return r.ec == std::errc() && r.ptr == end;
}

bool read_float(const OptionValue& v, float& out) {
  if (v.kind == OptionValue::Kind::integer || v.kind == OptionValue::Kind::number) {
    out =
        static_cast<float>(v.kind == OptionValue::Kind::integer ? static_cast<double>(v.integer) : v.number);
    return std::isfinite(out);
  }
  if (v.kind != OptionValue::Kind::text) return false;
  const char* end = v.text.data() + v.text.size();
  const auto r = std::from_chars(v.text.data(), end, out);
  return r.ec == std::errc() && r.ptr == end && std::isfinite(out);
}

bool read_bool(const OptionValue& v, bool& out) {
  if (v.kind == OptionValue::Kind::boolean) {
    out = v.boolean;
    return true;
  }
  if (v.kind != OptionValue::Kind::text) return false;
  if (v.text == "true") {
    out = true;
    return true;
  }
  if (v.text == "false") {
    out = false;
    return true;
  }
  return parse_word(kOnOffWords, v.text, out);
}

template <class E>
Status read_word(const OptionValue& v, E& out) {
  if (v.kind == OptionValue::Kind::text && parse_word(v.text, out)) return Status::ok();
  return Status::bad_input(expected_words<E>());
}

template <class E, std::size_t N>
Status read_word(const OptionValue& v, const Word<E> (&words)[N], E& out) {
  if (v.kind == OptionValue::Kind::text && parse_word(words, v.text, out)) return Status::ok();
  return Status::bad_input(expected_words(words));
}

Status expected(const std::string& what) { return Status::bad_input("expected " + what); }

// A distance: a number (scene units), "N%" or "auto". `positive`: 0 is not
// a distance (the AO and thickness reach).
Status read_distance(const OptionValue& v, Distance& out, bool positive) {
  const char* what = "a distance (scene units), N% or auto";
  if (v.kind == OptionValue::Kind::integer || v.kind == OptionValue::Kind::number) {
    const double d = v.kind == OptionValue::Kind::integer ? static_cast<double>(v.integer) : v.number;
    if (!(positive ? d > 0.0 : d >= 0.0) || !std::isfinite(d))
      return expected(positive ? "a distance > 0" : "a distance >= 0");
    out.kind = Distance::Kind::absolute;
    out.value = static_cast<float>(d);
    return Status::ok();
  }
  if (v.kind != OptionValue::Kind::text || !parse_distance(v.text, out)) return expected(what);
  return Status::ok();
}

// "auto" (0) or a number > 0.
Status read_range(const OptionValue& v, float& out) {
  if (v.kind == OptionValue::Kind::text && v.text == "auto") {
    out = 0.0f;
    return Status::ok();
  }
  float value = 0.0f;
  if (!read_float(v, value) || !(value > 0.0f)) return expected("a number > 0 or auto");
  out = value;
  return Status::ok();
}

Status read_path(const OptionValue& v, std::string& out) {
  if (v.kind != OptionValue::Kind::text || v.text.empty()) return expected("a path");
  const std::filesystem::path path(v.text);
  out = v.folder.empty() || path.is_absolute()
            ? v.text
            : (std::filesystem::path(v.folder) / path).lexically_normal().string();
  return Status::ok();
}

Status read_name(const OptionValue& v, std::string& out) {
  if (v.kind != OptionValue::Kind::text || v.text.empty()) return expected("a non-empty name");
  out = v.text;
  return Status::ok();
}

Status read_integer(const OptionValue& v, int& out) {
  return read_int(v, out) ? Status::ok() : expected("an integer");
}

Status read_number(const OptionValue& v, float& out) {
  return read_float(v, out) ? Status::ok() : expected("a number");
}

std::string number_text(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", value);
  return text;
}
std::string range_text(float range) { return range > 0.0f ? number_text(range) : "auto"; }
std::string no_words() { return ""; }
template <class E>
std::string words_of() {
  return word_list<E>(", ");
}

// The words of --tangents: the map's frame is computed, or the file's own.
inline constexpr Word<bool> kTangentsWords[] = {
    {"mikktspace", false, "computed (MikkTSpace)"},
    {"file", true, "the low mesh's own (glTF TANGENT, FBX tangents)"},
};

// A row whose value is one word of E's table, stored in the field `member`
// picks.
#define NMBAKE_WORD_ROW(key, E, field, help)                                                     \
  OptionSpec {                                                                                   \
    key, "WORD", help, [](BakeOptions& o, const OptionValue& v) { return read_word(v, field); }, \
        [](const BakeOptions& o) { return std::string(to_string(field)); }, words_of<E>          \
  }

}  // namespace

std::string high_name(const std::vector<std::string>& high_paths) {
  std::string name;
  for (const std::string& path : high_paths) name += (name.empty() ? "" : " + ") + path;
  return name;
}

namespace {

const OptionSpec kTable[] = {
    {"low", "PATH", "low-poly mesh with UVs (OBJ, PLY, glTF/GLB, FBX, DAE, 3DS)",
     [](BakeOptions& o, const OptionValue& v) { return read_path(v, o.low_path); },
     [](const BakeOptions& o) { return o.low_path; }, no_words, false, false},
    {"high", "PATH",
     "high-poly mesh (OBJ, PLY, glTF/GLB, FBX, DAE, 3DS, STL); repeatable: several files bake as one mesh",
     [](BakeOptions& o, const OptionValue& v) {
       std::vector<OptionValue> values;
       if (v.kind == OptionValue::Kind::list) {
         for (const std::string& text : v.list) {
           OptionValue one = OptionValue::of_text(text);
           one.folder = v.folder;
           values.push_back(std::move(one));
         }
       } else {
         values.push_back(v);
       }
       if (values.empty()) return expected("a path or a list of paths");
       std::vector<std::string> paths(values.size());
       for (std::size_t i = 0; i < values.size(); ++i) NMBAKE_TRY(read_path(values[i], paths[i]));
       o.high_paths = std::move(paths);
       return Status::ok();
     },
     [](const BakeOptions& o) { return high_name(o.high_paths); }, no_words, false, false, false, "", true},
    {"cage", "PATH",
     "cage mesh with the low mesh's topology (default: the pushed-out low surface, --cage-mode)",
     [](BakeOptions& o, const OptionValue& v) { return read_path(v, o.cage_path); },
     [](const BakeOptions& o) { return o.cage_path; }, no_words},
    {"size", "N|WxH", "map size",
     [](BakeOptions& o, const OptionValue& v) {
       int side = 0;
       if (read_int(v, side)) {
         o.width = o.height = side;
         return Status::ok();
       }
       const std::size_t x = v.kind == OptionValue::Kind::text ? v.text.find('x') : std::string::npos;
       if (x != std::string::npos && read_int(OptionValue::of_text(v.text.substr(0, x)), o.width) &&
           read_int(OptionValue::of_text(v.text.substr(x + 1)), o.height)) {
         return Status::ok();
       }
       return expected("N or WxH");
     },
     [](const BakeOptions& o) {
       return o.width == o.height ? std::to_string(o.width)
                                  : std::to_string(o.width) + "x" + std::to_string(o.height);
     },
     no_words},
    {"width", "N", "map width (size sets both)",
     [](BakeOptions& o, const OptionValue& v) { return read_integer(v, o.width); },
     [](const BakeOptions& o) { return std::to_string(o.width); }, no_words},
    {"height", "N", "map height (size sets both)",
     [](BakeOptions& o, const OptionValue& v) { return read_integer(v, o.height); },
     [](const BakeOptions& o) { return std::to_string(o.height); }, no_words},
    {"samples", "N|adaptive",
     "samples per texel: 1, 4, 16, 64, or adaptive (1, then adaptive_max where the normal varies)",
     [](BakeOptions& o, const OptionValue& v) {
       if (v.kind == OptionValue::Kind::text && v.text == "adaptive") {
         o.adaptive = true;
         return Status::ok();
       }
       if (!read_int(v, o.samples)) return expected("1, 4, 16, 64 or adaptive");
       o.adaptive = false;
       return Status::ok();
     },
     [](const BakeOptions& o) { return o.adaptive ? std::string("adaptive") : std::to_string(o.samples); },
     no_words},
    {"adaptive_max", "N", "samples of a refined texel with samples = adaptive: 4, 16, 64",
     [](BakeOptions& o, const OptionValue& v) { return read_integer(v, o.adaptive_options.max_samples); },
     [](const BakeOptions& o) { return std::to_string(o.adaptive_options.max_samples); }, no_words},
    {"adaptive_normal", "X", "refine where the stored vector's second difference between texels exceeds this",
     [](BakeOptions& o, const OptionValue& v) { return read_number(v, o.adaptive_options.normal_threshold); },
     [](const BakeOptions& o) { return number_text(o.adaptive_options.normal_threshold); }, no_words},
    {"adaptive_depth", "X", "refine where the hit distance's second difference exceeds this many texels",
     [](BakeOptions& o, const OptionValue& v) { return read_number(v, o.adaptive_options.depth_threshold); },
     [](const BakeOptions& o) { return number_text(o.adaptive_options.depth_threshold); }, no_words},
    {"adaptive_spread", "X",
     "take adaptive_max samples where a refined texel's 4 samples spread more (radians)",
     [](BakeOptions& o, const OptionValue& v) { return read_number(v, o.adaptive_options.spread_threshold); },
     [](const BakeOptions& o) { return number_text(o.adaptive_options.spread_threshold); }, no_words},
    {"adaptive_border", "X", "at a chart border, refine where the normal's first difference exceeds this",
     [](BakeOptions& o, const OptionValue& v) { return read_number(v, o.adaptive_options.border_threshold); },
     [](const BakeOptions& o) { return number_text(o.adaptive_options.border_threshold); }, no_words},
    NMBAKE_WORD_ROW("space", NormalSpace, o.encode.space, "the space the normal is stored in"),
    {"preset", "ENGINE",
     "the engine the map is for: sets green, bitangent, tbn and blue (each of those given too overrides it)",
     [](BakeOptions& o, const OptionValue& v) {
       EnginePreset preset;
       if (v.kind != OptionValue::Kind::text || !find_engine_preset(v.text, preset)) {
         return expected("one of: " + engine_preset_names());
       }
       o.preset = v.text;
       apply_engine_preset(preset, {}, o.encode.green, o.encode.decode);
       return Status::ok();
     },
     [](const BakeOptions& o) { return o.preset.empty() ? std::string("none") : o.preset; },
     engine_preset_names, false, true, true},
    NMBAKE_WORD_ROW("green", GreenChannel, o.encode.green,
                    "the green channel (up: OpenGL, down: DirectX); overrides the preset's"),
    NMBAKE_WORD_ROW("bitangent", Bitangent, o.encode.decode.bitangent, "how the engine gets B"),
    {"tbn", "WORD", "the engine's T, B, N before the decode",
     [](BakeOptions& o, const OptionValue& v) {
       return read_word(v, kFrameRuleWords, o.encode.decode.unit_frame);
     },
     [](const BakeOptions& o) { return std::string(word_of(kFrameRuleWords, o.encode.decode.unit_frame)); },
     [] { return word_list(kFrameRuleWords, ", "); }},
    {"blue", "WORD", "the engine's z",
     [](BakeOptions& o, const OptionValue& v) {
       return read_word(v, kBlueRuleWords, o.encode.decode.rebuild_blue);
     },
     [](const BakeOptions& o) { return std::string(word_of(kBlueRuleWords, o.encode.decode.rebuild_blue)); },
     [] { return word_list(kBlueRuleWords, ", "); }},
    {"dither", "on|off", "8-bit outputs (png8, tga): ordered dither, or rounded",
     [](BakeOptions& o, const OptionValue& v) {
       return read_bool(v, o.dither) ? Status::ok() : Status::bad_input(expected_words(kOnOffWords));
     },
     [](const BakeOptions& o) { return std::string(word_of(kOnOffWords, o.dither)); },
     [] { return word_list(kOnOffWords, ", "); }},
    {"front", "DISTANCE",
     "how far outside the low surface rays start: scene units, N% of the low diagonal, or auto",
     [](BakeOptions& o, const OptionValue& v) { return read_distance(v, o.rays.front, false); },
     [](const BakeOptions& o) { return to_string(o.rays.front); }, no_words},
    {"back", "DISTANCE", "how far inside the low surface rays search: scene units, N%, or auto",
     [](BakeOptions& o, const OptionValue& v) { return read_distance(v, o.rays.back, false); },
     [](const BakeOptions& o) { return to_string(o.rays.back); }, no_words},
    NMBAKE_WORD_ROW("hit", HitRule, o.rays.hit, "which hit a ray keeps"),
    NMBAKE_WORD_ROW("cage_mode", CageMode, o.rays.cage_mode, "how the default cage is pushed out"),
    {"edge_band", "X", "banded cage: the band around hard edges, in units of front + back (0 to 100)",
     [](BakeOptions& o, const OptionValue& v) { return read_number(v, o.rays.edge_band); },
     [](const BakeOptions& o) { return number_text(o.rays.edge_band); }, no_words},
    NMBAKE_WORD_ROW("retry_misses", RetryMisses, o.rays.retry_misses,
                    "trace a ray that missed again, out and in up to a quarter of the diagonal"),
    {"ignore_backfaces", "", "skip high triangles that face away from the ray",
     [](BakeOptions& o, const OptionValue& v) {
       return read_bool(v, o.rays.ignore_backfaces) ? Status::ok() : expected("true or false");
     },
     [](const BakeOptions& o) { return std::string(o.rays.ignore_backfaces ? "true" : "false"); }, no_words,
     true},
    NMBAKE_WORD_ROW("high_normals", HighNormals, o.encode.high_normals, "the high mesh's normals at a hit"),
    NMBAKE_WORD_ROW("high_normal_maps", HighNormalMaps, o.high_normal_maps,
                    "the high's normal textures perturb its normals (auto: when its materials have one)"),
    {"padding", "N", "texels of dilation around charts (0 to 4096)",
     [](BakeOptions& o, const OptionValue& v) { return read_integer(v, o.padding); },
     [](const BakeOptions& o) { return std::to_string(o.padding); }, no_words},
    NMBAKE_WORD_ROW("build_quality", BuildQuality, o.build_quality, "BVH build quality"),
    NMBAKE_WORD_ROW("bvh", BvhMemory, o.bvh_memory, "BVH layout"),
    NMBAKE_WORD_ROW("encode", TangentEncode, o.encode.tangent_encode, "tangent-space encode"),
    NMBAKE_WORD_ROW("tangent_basis", TangentBasis, o.tangent_basis, "the basis the map is encoded in"),
    {"tangents", "WORD", "the map's tangent frame: computed, or the low mesh's own",
     [](BakeOptions& o, const OptionValue& v) {
       bool file = false;
       NMBAKE_TRY(read_word(v, kTangentsWords, file));
       // mikktspace leaves a comparison basis (tangent_basis) as it is.
       if (file)
         o.tangent_basis = TangentBasis::file;
       else if (o.tangent_basis == TangentBasis::file)
         o.tangent_basis = TangentBasis::mikktspace;
       return Status::ok();
     },
     [](const BakeOptions& o) {
       return std::string(word_of(kTangentsWords, o.tangent_basis == TangentBasis::file));
     },
     [] { return word_list(kTangentsWords, ", "); }},
    {"uv_set", "N", "the low mesh's UV set: glTF TEXCOORD_N, FBX UV channel N (0 to 7)",
     [](BakeOptions& o, const OptionValue& v) { return read_integer(v, o.uv_set); },
     [](const BakeOptions& o) { return std::to_string(o.uv_set); }, no_words},
    {"max_memory", "BYTES", "refuse a bake whose estimated memory is above this (e.g. 8G)",
     [](BakeOptions& o, const OptionValue& v) {
       if (v.kind == OptionValue::Kind::integer && v.integer > 0) {
         o.max_memory_bytes = static_cast<std::uint64_t>(v.integer);
         return Status::ok();
       }
       if (v.kind == OptionValue::Kind::text && parse_memory_size(v.text, o.max_memory_bytes))
         return Status::ok();
       return expected("bytes, or a number with K, M, G or T");
     },
     [](const BakeOptions& o) {
       return o.max_memory_bytes == 0 ? std::string("available") : memory_text(o.max_memory_bytes);
     },
     no_words},
    NMBAKE_WORD_ROW("match", MatchMode, o.match.mode, "parts into bake groups"),
    NMBAKE_WORD_ROW("unmatched", Unmatched, o.match.unmatched, "low parts with no high match"),
    {"low_suffix", "NAME", "name suffix of low parts (X_low bakes from X_high, X_high_1, X_high.001)",
     [](BakeOptions& o, const OptionValue& v) { return read_name(v, o.match.low_suffix); },
     [](const BakeOptions& o) { return o.match.low_suffix; }, no_words},
    {"high_suffix", "NAME", "name suffix of high parts",
     [](BakeOptions& o, const OptionValue& v) { return read_name(v, o.match.high_suffix); },
     [](const BakeOptions& o) { return o.match.high_suffix; }, no_words},
    {"cage_suffix", "NAME", "name suffix of cage parts (X_cage is the cage of X_low)",
     [](BakeOptions& o, const OptionValue& v) { return read_name(v, o.match.cage_suffix); },
     [](const BakeOptions& o) { return o.match.cage_suffix; }, no_words},
    {"groups_per_scene", "N", "bake groups sharing one BVH through ray masks, 1-32 (0: auto; for benchmarks)",
     [](BakeOptions& o, const OptionValue& v) { return read_integer(v, o.groups_per_scene); },
     [](const BakeOptions& o) { return std::to_string(o.groups_per_scene); }, no_words},
    {"debug_dump", "PREFIX", "also write PREFIX_coverage.png, PREFIX_misses.png, PREFIX_distance.exr",
     [](BakeOptions& o, const OptionValue& v) { return read_path(v, o.debug_dump_prefix); },
     [](const BakeOptions& o) { return o.debug_dump_prefix; }, no_words, false, false},
    {"maps", "LIST",
     "the maps to bake from the same rays (a list, or names with commas); several need <MAP> in outputs",
     [](BakeOptions& o, const OptionValue& v) {
       std::vector<MapKind> maps;
       if (v.kind == OptionValue::Kind::list) {
         for (const std::string& name : v.list) NMBAKE_TRY(parse_map_list(name, maps));
       } else if (v.kind == OptionValue::Kind::text) {
         NMBAKE_TRY(parse_map_list(v.text, maps));
       } else {
         return expected("a list of map names, e.g. [\"normal\", \"ao\"]");
       }
       if (maps.empty()) return expected("at least one map");
       o.maps = std::move(maps);
       return Status::ok();
     },
     [](const BakeOptions& o) { return map_list_text(o.maps); }, words_of<MapKind>, false, true, false,
     "map"},
    {"height_range", "R|auto", "height map in integer files: heights in [-R, R] scene units fill 0..1",
     [](BakeOptions& o, const OptionValue& v) { return read_range(v, o.height_range); },
     [](const BakeOptions& o) { return range_text(o.height_range); }, no_words},
    {"curvature_range", "R|auto",
     "curvature map in integer files: mean curvature in [-R, R] (1/scene units) fills 0..1 (auto: 99th "
     "percentile)",
     [](BakeOptions& o, const OptionValue& v) { return read_range(v, o.curvature_range); },
     [](const BakeOptions& o) { return range_text(o.curvature_range); }, no_words},
    {"ao_rays", "N", "AO (and bent normal) rays per sample, 1-4096",
     [](BakeOptions& o, const OptionValue& v) { return read_integer(v, o.ao_rays); },
     [](const BakeOptions& o) { return std::to_string(o.ao_rays); }, no_words},
    {"ao_distance", "DISTANCE",
     "AO: occluders further than this do not count: units, N% of the diagonal, auto (10%)",
     [](BakeOptions& o, const OptionValue& v) { return read_distance(v, o.ao_distance, true); },
     [](const BakeOptions& o) { return to_string(o.ao_distance); }, no_words},
    {"thickness_rays", "N", "thickness rays per sample, 1-4096",
     [](BakeOptions& o, const OptionValue& v) { return read_integer(v, o.thickness_rays); },
     [](const BakeOptions& o) { return std::to_string(o.thickness_rays); }, no_words},
    {"thickness_distance", "DISTANCE",
     "thickness: search distance, also white in integer files: units, N%, auto (10%)",
     [](BakeOptions& o, const OptionValue& v) { return read_distance(v, o.thickness_distance, true); },
     [](const BakeOptions& o) { return to_string(o.thickness_distance); }, no_words},
    NMBAKE_WORD_ROW("id_source", IdSource, o.id_source, "what the id map colours"),
    {"id_palette", "PATH", "the id map's colours by part or material name: a TOML file of NAME = \"#RRGGBB\"",
     [](BakeOptions& o, const OptionValue& v) { return read_path(v, o.id_palette); },
     [](const BakeOptions& o) { return o.id_palette; }, no_words},
    {"pack", "FILE=r:MAP,g:MAP,...",
     "a packed output (repeatable): channels of the baked maps, e.g. orm.png=r:ao,g:roughness,b:metallic; a "
     "channel is MAP, MAP.r|g|b, 1-MAP or a number",
     [](BakeOptions& o, const OptionValue& v) {
       std::vector<std::string> texts;
       if (v.kind == OptionValue::Kind::list) {
         texts = v.list;
       } else if (v.kind == OptionValue::Kind::text) {
         texts = {v.text};
       } else {
         return expected("FILE=r:MAP,g:MAP,... or a list of them");
       }
       std::vector<PackSpec> packs;
       for (const std::string& text : texts) {
         PackSpec pack;
         NMBAKE_TRY(parse_pack(text, pack));
         // A job file's pack lies beside its outputs: relative to the job.
         const std::filesystem::path path(pack.path);
         if (!v.folder.empty() && !path.is_absolute())
           pack.path = (std::filesystem::path(v.folder) / path).lexically_normal().string();
         packs.push_back(std::move(pack));
       }
       o.packs = std::move(packs);
       return Status::ok();
     },
     [](const BakeOptions& o) {
       std::string text;
       for (const PackSpec& p : o.packs) text += (text.empty() ? "" : "; ") + pack_text(p);
       return text;
     },
     no_words, false, false, false, "", true},
};

#undef NMBAKE_WORD_ROW

}  // namespace

std::span<const OptionSpec> bake_option_table() { return kTable; }

const OptionSpec* find_option(std::string_view key) {
  for (const OptionSpec& spec : kTable) {
    if (spec.key == key) return &spec;
  }
  return nullptr;
}

std::string flag_of(const OptionSpec& spec) {
  std::string flag = "--" + std::string(spec.flag.empty() ? spec.key : spec.flag);
  for (char& c : flag) c = c == '_' ? '-' : c;
  return flag;
}

std::string help_of(const OptionSpec& spec) {
  std::string text(spec.help);
  const std::string words = spec.words();
  if (!words.empty()) text += ": " + words;
  const std::string shown = spec.show(BakeOptions{});
  if (!shown.empty() && !spec.is_switch) text += " (default " + shown + ")";
  return text;
}

std::string options_json(const BakeOptions& options) {
  nlohmann::ordered_json out = nlohmann::ordered_json::object();
  for (const OptionSpec& spec : kTable) out[std::string(spec.key)] = spec.show(options);
  nlohmann::ordered_json outputs = nlohmann::ordered_json::array();
  for (const OutputSpec& o : options.outputs) {
    outputs.push_back({{"path", o.path}, {"format", to_string(o.format)}, {"format_given", o.format_given}});
  }
  out["outputs"] = outputs;
  return out.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

Status apply_options(const std::vector<GivenOption>& given, BakeOptions& options) {
  for (const bool first : {true, false}) {
    for (const GivenOption& g : given) {
      if (g.spec->first != first) continue;
      if (const Status s = g.spec->set(options, g.value); !s) {
        const std::string shown = g.is_flag && !g.spec->is_switch ? " " + printable_text(g.value.text) : "";
        return Status::bad_input(g.where + shown + ": " + s.message());
      }
    }
  }
  return Status::ok();
}

}  // namespace nmbake
