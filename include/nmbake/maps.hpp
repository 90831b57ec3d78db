// The map set (DESIGN.md, "A map set, one set of rays"): the maps an artist
// bakes beside the normal map, from the same raster, rays and hits.
//
//   raster -> trace -> [occlusion rays] -> maps (encode) -> dilate -> write
//
// A map is a small module (src/maps/): what it reads from a band's samples
// and hits, how it turns them into texels, how it is dilated, and what an
// integer file stores. Every map's texel is the mean over the texel's samples
// (a sample whose ray missed takes the map's miss value), so all maps share
// the normal map's anti-aliasing. The write stage does not know which map it
// writes: it gets a float image and, for integer formats, the map's range.
//
// clang-format off
// | map            | texel (float, EXR)                          | integer files (PNG, TIFF)             | miss value |
// |----------------|---------------------------------------------|---------------------------------------|------------|
// | normal         | 0.5 n + 0.5 (encode.hpp)                     | the same                              | low normal |
// | height         | signed distance from the low surface to the hit along the ray, scene units (> 0 outside) | 0.5 + h / (2 R): R = --height-range, or the largest |h| of the map (auto) | 0 |
// | ao             | share of cosine-weighted rays unoccluded within --ao-distance (occlusion.hpp) | the same | 1 |
// | bent-normal    | mean unoccluded AO direction, encoded as the normal map (space, green) | the same | low normal |
// | curvature      | mean curvature H of the high surface at the hit, 1/scene units (> 0 convex) | 0.5 + H / (2 R): R = --curvature-range, or the 99th percentile of |H| (auto) | 0 |
// | thickness      | distance through the high mesh (occlusion.hpp), scene units | d / D, D = --thickness-distance (black thin, white thick, as Substance) | 0 |
// | position       | (hit - min) / (max - min) per axis, the high mesh's bounding box | the same | low point |
// | object-normal  | 0.5 n + 0.5, world space (the normal map's object space) | the same | low normal |
// | miss           | share of the texel's samples whose ray missed | the same | 1 |
// | vertex-color   | the high mesh's vertex colour (RGB, sRGB-encoded) at the hit (PLY, OBJ "v x y z r g b", glTF COLOR_0, FBX/Collada colours: load.hpp) | the same | black |
// | id             | the colour of the hit's material or part (IdSource): the one most of the texel's samples hit; a material's own colour (Kd, baseColorFactor, sRGB-encoded) when the file gives one that no other material shares, else part_color() of the name | the same | black |
// | base-color     | the hit material's base colour factor x its texture (textures.hpp), linear RGB | sRGB-encoded | black |
// | roughness      | roughness factor x texture channel (glTF: G of metallicRoughness)  | the same | 0 |
// | metallic       | metallic factor x texture channel (glTF: B of metallicRoughness)   | the same | 0 |
// | emissive       | emissive factor x its texture, linear RGB                        | sRGB-encoded | black |
// | opacity        | base colour alpha x the opacity texture (glTF: base colour alpha, with alphaMode BLEND or MASK; MTL d, map_d) | the same | 0 |
// clang-format on
//
// Single-channel maps (height, ao, curvature, thickness, miss) are written
// as grey files. Default formats for `.png` outputs: 16-bit, except ao,
// curvature, thickness, miss, vertex-color and id: 8-bit (an explicit format
// wins).
//
// Curvature: mean curvature per high triangle from the derivative of its
// interpolated vertex normals (the shape operator estimate of Rusinkiewicz,
// "Estimating Curvatures and Their Derivatives on Triangle Meshes", 3DPVT
// 2004, per face: H = tr(G^-1 M) / 2, G the Gram matrix of two edges, M their
// dot products with the normal differences), averaged per vertex weighted by
// area (one pass over the high mesh), interpolated at the hit.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "nmbake/common.hpp"
#include "nmbake/dilate.hpp"
#include "nmbake/encode.hpp"
#include "nmbake/image.hpp"
#include "nmbake/mesh.hpp"
#include "nmbake/occlusion.hpp"
#include "nmbake/parts.hpp"
#include "nmbake/raster.hpp"
#include "nmbake/surface.hpp"
#include "nmbake/tangents.hpp"
#include "nmbake/textures.hpp"
#include "nmbake/trace.hpp"

namespace nmbake {

enum class MapKind : std::uint8_t {
  normal,
  height,
  ao,
  bent_normal,
  curvature,
  thickness,
  position,
  object_normal,
  vertex_color,
  id,
  miss,
  base_color,
  roughness,
  metallic,
  emissive,
  opacity
};

inline constexpr Word<MapKind> kMapKindWords[] = {
    {"normal", MapKind::normal, "tangent- or object-space normal map"},
    {"height", MapKind::height, "distance of the high surface from the low"},
    {"ao", MapKind::ao, "ambient occlusion"},
    {"bent-normal", MapKind::bent_normal, "the mean unoccluded direction"},
    {"curvature", MapKind::curvature, "the high surface's mean curvature"},
    {"thickness", MapKind::thickness, "how far rays travel inside the high mesh"},
    {"position", MapKind::position, "the hit point in the high mesh's bounds"},
    {"object-normal", MapKind::object_normal, "the high normal in object space"},
    {"vertex-color", MapKind::vertex_color, "the high mesh's vertex colour"},
    {"id", MapKind::id, "a colour per part or material"},
    {"miss", MapKind::miss, "white where a ray found no high surface"},
    {"base-color", MapKind::base_color, "the high's base colour (its materials' textures and factors)"},
    {"roughness", MapKind::roughness, "the high's roughness (textures and factors)"},
    {"metallic", MapKind::metallic, "the high's metallic (textures and factors)"},
    {"emissive", MapKind::emissive, "the high's emission (textures and factors)"},
    {"opacity", MapKind::opacity, "the high's opacity (alpha; textures and factors)"},
};
NMBAKE_WORDS(MapKind, kMapKindWords)
// Appends the maps of "normal,height" (any number of names, commas, spaces)
// to `out`, skipping names already there (the order of first mention is
// kept). bad_input naming the unknown word and the known ones.
Status parse_map_list(const std::string& text, std::vector<MapKind>& out);
// "normal, height, ao"
std::string map_list_text(const std::vector<MapKind>& maps);

// What a map is, whatever the bake.
struct MapTraits {
  int channels = 3;
  DilateMode dilate = DilateMode::mean;
  PixelFormat png_format = PixelFormat::png16;  // for a .png output without an explicit format
  bool occlusion_rays = false;                  // needs trace_occlusion()
  bool thickness_rays = false;                  // needs trace_thickness()
  bool implemented = true;  // false: refused by validate_options() (every map is implemented)
  bool srgb = false;        // a colour: integer files store its sRGB encoding, float files the linear value
  bool surface = false;     // reads the high's materials and textures (texture transfer)
};
MapTraits map_traits(MapKind map);

// Which of the high's material attributes the maps read.
TextureNeeds texture_needs(const std::vector<MapKind>& maps);

// What the texture transfer maps read, in the scene's triangle order (after
// groups): per triangle its material (an index into `materials`, whose last
// entry is the default for triangles without a definition), the corners'
// high UVs, and how much UV one scene unit covers (sqrt(UV area / area), 0
// for a degenerate triangle: the finest mip level); the textures read.
// With the high's normal textures (HighNormalMaps): the high's MikkTSpace
// tangents from its corner UVs, 3 per triangle in the scene's order, on the
// triangles whose material has a normal texture ((0, 0, 0, 0) elsewhere).
struct SurfaceTransfer {
  std::vector<Material> materials;
  std::vector<MaterialTextures> material_textures;  // parallel to materials
  std::vector<std::uint32_t> triangle_material;
  std::vector<glm::vec2> corner_uv;
  std::vector<float> uv_density;
  TextureSet textures;
  std::vector<glm::vec4> corner_tangent;  // empty without the high's normal textures
  TangentStats tangent_stats;             // of corner_tangent
  double tangent_seconds = 0.0;
  bool normal_maps() const { return !corner_tangent.empty(); }
};

// What the id map colours: the high mesh's parts (OBJ o/g, glTF nodes, FBX
// models) or its materials (OBJ usemtl, glTF primitive materials, FBX and
// Collada materials); automatic: materials when the high mesh has a named
// material (Mesh::has_named_materials()), else parts. vertex_color: the
// high's vertex colours (polypaint): each triangle takes the colour most of
// its corners have (the first corner's when all three differ), at 8 bits.
enum class IdSource : std::uint8_t { automatic, part, material, vertex_color };
inline constexpr Word<IdSource> kIdSourceWords[] = {
    {"auto", IdSource::automatic, "materials when the high mesh names one, else parts"},
    {"part", IdSource::part, "a colour per high part"},
    {"material", IdSource::material, "a colour per high material"},
    {"vertex-color", IdSource::vertex_color, "the high's vertex colours, one per triangle"},
};
NMBAKE_WORDS(IdSource, kIdSourceWords)
// `requested` for `high`: part, material or vertex_color, never automatic.
IdSource resolve_id_source(IdSource requested, const Mesh& high);

// The artist's colours for the id map (--id-palette): names of parts or
// materials with an 8-bit sRGB colour, as a TOML file of `NAME = "#RRGGBB"`
// lines (quoted names for any characters: `"rubber grip" = "#202020"`).
// A name the palette gives takes its colour even when another name shares
// it (two materials one mask, as the artist chose); the names it does not
// give are coloured as without a palette.
struct IdPalette {
  std::vector<std::pair<std::string, glm::vec3>> colors;  // display values in [0, 1]
  const glm::vec3* find(const std::string& name) const;
};
// bad_input naming `path` (and the line) and what is wrong: not TOML, a
// value that is not "#RRGGBB", a table.
Status read_id_palette(const std::string& path, IdPalette& out);

// Output paths name maps with a token: `-o asset_<MAP>.png`.
inline constexpr const char* kMapToken = "<MAP>";
bool has_map_token(const std::string& path);
std::string map_path(const std::string& path, MapKind map);  // every <MAP> replaced by the map's name

// The map's format for an output: an explicit format as given; else from the
// extension, `.png` taking the map's own depth.
PixelFormat map_format(MapKind map, PixelFormat format, bool format_given, const std::string& path);

// Resolved settings of the map set (scene units).
struct MapSettings {
  std::vector<MapKind> maps{MapKind::normal};
  EncodeOptions encode;          // the normal map's (space, green, encode); bent-normal uses space and green
  float height_range = 0.0f;     // > 0: given; 0: auto
  float curvature_range = 0.0f;  // > 0: given; 0: auto
  OcclusionOptions occlusion;    // rays, distance (bent: set when bent-normal is baked)
  ThicknessOptions thickness;
  Bounds position_bounds;  // the high mesh's
  // Read by encode_band() only (a merge of tiles has none of them):
  // per high vertex (curvature maps; empty otherwise): vertex_mean_curvature();
  const std::vector<float>* vertex_curvature = nullptr;
  // the id map: per high triangle (in the scene's order) the index of its
  // part or material (id_source, resolved), and per index its colour
  // (part_color() of the name).
  IdSource id_source = IdSource::part;
  const std::vector<std::uint32_t>* triangle_id = nullptr;
  const std::vector<glm::vec3>* id_colors = nullptr;
  // The texture transfer maps: the high's surface data, and the whole map's
  // height (a texel's footprint, textures.hpp).
  const SurfaceTransfer* transfer = nullptr;
  int map_height = 0;

  bool has(MapKind map) const;
};

// One map's figures for the report, in order: ranges used, counters of
// fallbacks, rays. `tile` is the UDIM tile.
struct MapReport {
  MapKind map = MapKind::normal;
  int tile = 1001;
  std::vector<std::string> outputs;
  std::vector<std::pair<std::string, double>> figures;
  double figure(const std::string& name) const;  // 0 when absent
};

// The id map's colour of a part or material: a hue from the FNV-1a hash of
// its name (the same name, the same colour, in any file and bake, whether it
// names a part or a material), saturation 0.6, value 0.9.
glm::vec3 part_color(const std::string& name);

struct CurvatureStats {
  std::uint64_t degenerate_triangles = 0;  // zero area or singular edges: no weight
  std::uint64_t isolated_vertices = 0;     // no triangle with weight: H = 0
};
// Mean curvature per vertex of `high` (see above) from `normals` (one unit
// normal per vertex: the mesh's smooth normals). Parallel; the result does
// not depend on the thread count (per-vertex sums in triangle order).
std::vector<float> vertex_mean_curvature(const Mesh& high, const std::vector<glm::vec3>& normals,
                                         CurvatureStats& stats);

// What the map set reads from the whole high mesh, once per bake: its
// bounds (position), vertex curvature (curvature), and each triangle's part
// or material with their names and colours (id), for the maps in `maps`
// only. The transfer maps' per-triangle data (materials, corner UVs) need
// high.corner_uvs and material_defs; its textures are handed in.
struct MapMeshData {
  Bounds position_bounds;
  std::vector<float> vertex_curvature;
  CurvatureStats curvature;
  IdSource id_source = IdSource::part;     // resolved
  std::vector<std::uint32_t> triangle_id;  // in the scene's triangle order (after groups)
  std::vector<glm::vec3> id_colors;
  std::vector<std::pair<std::string, glm::vec3>> ids;  // name, colour; in order of first triangle
  SurfaceTransfer transfer;
  // Points `settings` at this data (which must outlive it).
  void apply(MapSettings& settings) const;
};
// From `high` as loaded, normals prepared, before group_high_indices()
// reorders its triangles; `groups` tells how they will be reordered. The
// vertex curvature of a mesh without normals (--high-normals face) uses
// area-weighted ones. The id map's names are `id_source`'s
// (resolve_id_source()); an explicit material source on a mesh without
// named materials is the caller's error to report first (all "" then).
// `textures`: the high's textures the transfer maps read
// (load_material_textures(); empty without transfer maps), kept in `out`.
// `palette`: the id map's colours the artist gave (--id-palette).
// `high_tangents` (compute_high_tangents(); empty: none): the normal bake
// reads the high's normal textures (the textures hold them:
// load_material_textures() with TextureNeeds::normal).
struct HighTangents {
  std::vector<glm::vec4> corner;  // 3 per triangle of the high, in the file's order
  TangentStats stats;
  double seconds = 0.0;
};
void prepare_map_mesh(const Mesh& high, const std::vector<MapKind>& maps, IdSource id_source,
                      const IdPalette& palette, const BakeGroups& groups, TextureSet textures,
                      MapMeshData& out, HighTangents high_tangents = {});
// The high's MikkTSpace tangents from its corner UVs on the triangles whose
// material names a normal texture (compute_corner_uv_tangents()); none when
// no triangle's does. Independent of the textures' reading: a bake runs the
// two side by side (a PNG decodes on one core, the tangents run on one).
HighTangents compute_high_tangents(const Mesh& high);

// What the bands of a map set counted: per map (in the set's order) the
// figures its module added up band by band (fallback counters), and the rays
// cast from the hits. A tile of rows carries its share (task.hpp); a merge
// adds the tiles' shares up, so its report has the whole bake's figures.
// The values are whole numbers: their sums do not depend on the order.
struct MapCounts {
  std::vector<std::vector<std::pair<std::string, double>>> maps;
  OcclusionStats occlusion;
  ThicknessStats thickness;
};

// The maps of one map (a UDIM tile's, or a tile of rows), band by band:
//   MapSet set(settings, ...); for each band: trace_rays(); encode_band();
//   finish(coverage, padding); image(map) and integer_mapping(map) for each output.
// A merge of tiles of rows (task.hpp) builds the set for the whole map from
// the settings the tiles carry, fills image() with their texels, adds their
// counts() with add_counts(), and finishes and writes as a whole bake does.
// Only encoding reads the high mesh's data (vertex curvature, parts): the
// finishing and the files need none of it.
class MapSet {
 public:
  // Rows [first_row, last_row) of a width-wide map.
  MapSet(const MapSettings& settings, int width, int first_row, int last_row);
  ~MapSet();
  MapSet(const MapSet&) = delete;
  MapSet& operator=(const MapSet&) = delete;

  // The extra rays a band's maps need (AO and bent normals, thickness),
  // from the band's hits: nothing when no map needs them.
  void trace_rays(const HighScene& scene, const Mesh& high, const LowSurface& surface,
                  const TexelSamples& samples, const Hits& hits);
  bool needs_rays() const;
  // Every map's texels of the band (after trace_rays()). The normal map's
  // encode counters go to `normal_stats`, as before the map set.
  void encode_band(const LowSurface& surface, const TexelSamples& samples, const Mesh& high, const Hits& hits,
                   EncodeStats& normal_stats);
  // After the last band: ranges (auto height and curvature) from the
  // covered texels, then every map dilated by `padding` (`coverage` grows
  // with it, as dilate() does). Adds to `dilate`.
  void finish(std::vector<std::uint8_t>& coverage, int padding, DilateStats& dilate);
  // How integer files (PNG, TIFF, TGA) of `map` store its texels: as
  // v * scale + offset (height and curvature 0.5 + v / 2R, thickness
  // v / distance; others v), mapped by the writer while it quantises
  // (WriteOptions), so no mapped copy of the image is made. Float files store v.
  void integer_mapping(MapKind map, float& scale, float& offset) const;
  // The map's image (its raw texels; dilated after finish()).
  Image& image(MapKind map);
  // Figures of every map, in the set's order.
  std::vector<MapReport> reports(int tile) const;
  // What the bands counted so far (before finish()), and the counts of
  // another part of the same map (a tile's, of a set of the same maps)
  // added to this set's.
  MapCounts counts() const;
  void add_counts(const MapCounts& counts);

  struct Module;  // src/maps/modules.hpp

 private:
  std::vector<std::unique_ptr<Module>> modules_;
  MapSettings settings_;
  int first_row_, last_row_;
  // Per sample of the current band, from trace_rays().
  std::vector<float> visibility_, thickness_;
  std::vector<glm::vec3> bent_;
  OcclusionStats occlusion_stats_;
  ThicknessStats thickness_stats_;
};

}  // namespace nmbake
