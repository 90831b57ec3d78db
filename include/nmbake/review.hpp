// Reviewing a bake in 3D (`nmbake view`): a binary glTF of the low mesh as
// the maps were baked for it (the bake's normals, MikkTSpace tangents as
// glTF TANGENT, the triangles as baked, one node per part, one material per
// UDIM tile wearing its maps) and one self-contained HTML page (three.js
// inlined, the .glb embedded) that shows it. The page decodes the normal map
// in its own shader exactly as `nmbake preview` does (preview.hpp: T, N
// interpolated and not normalised, B = sign cross(N, T) per pixel, green
// up), lit with the preview's camera and Blinn-Phong lights in its
// "compare" mode, so that a screenshot of the page and the preview's
// low+map panel can be compared pixel for pixel.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "nmbake/common.hpp"
#include "nmbake/preview.hpp"

namespace nmbake {

// One baked map: its kind (a word of the map set: normal, ao, height,
// curvature, base-color, ...) and its file; `path` may carry <UDIM> (one
// file per tile the low mesh uses).
struct ReviewMap {
  std::string kind;
  std::string path;
};

struct ReviewOptions {
  std::string low;     // the low mesh the maps were baked for (with UVs)
  std::string high;    // optional: shown beside the low, and framed by the camera as the preview frames it
  std::string report;  // optional: the bake report (JSON), its figures shown in the page
  std::vector<ReviewMap> maps;
  // The high mesh above this many triangles is simplified by vertex
  // clustering on a uniform grid (the grid halved until it fits) for the page.
  std::uint64_t high_budget = 200000;
  ViewOptions view;  // the page's initial camera and key light (as `nmbake preview`'s)
  std::string three_dir = "/usr/share/javascript/three";  // libjs-three (r111)
  // Serve mode: the page polls `serve_url`/state and re-fetches maps from
  // `serve_url`/map/I/TILE.png when their files change (review_map_png()).
  bool served = false;
};

struct ReviewStats {
  std::uint64_t low_triangles = 0, low_vertices = 0;  // of the .glb (vertices split per tangent and tile)
  std::uint64_t high_triangles = 0, high_triangles_shown = 0;
  std::vector<int> tiles;
  std::uint64_t glb_bytes = 0, html_bytes = 0;
  std::uint64_t fallback_tangents = 0;
};

// The review .glb and page as bytes. bad_input naming the file for a
// missing or unreadable mesh, map or report, a map kind that is not known,
// a map whose size differs across tiles, or libjs-three missing (naming the
// path and the package).
Status build_review(const ReviewOptions& options, std::string& glb, std::string& html, ReviewStats& stats);

// A map file as the page shows it: an 8-bit PNG (16-bit and float maps
// rounded; height, curvature and thickness stretched from their min..max
// to 0..1, `range` set to that min and max, else 0 and 1).
Status review_map_png(const std::string& kind, const std::string& path, std::string& png, float range[2]);

// Which map kinds the page knows, for messages.
const char* review_map_kinds();
bool review_map_kind_known(const std::string& kind);

}  // namespace nmbake
