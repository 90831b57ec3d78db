// nmbake-gen maplab: every map of the map set baked on the analytic scenes
// of map_lab.hpp and scored against its closed form; writes DIR/maps_lab.csv
// and DIR/maps_lab.md (tools/chart-maps draws the AO chart from the CSV).
#include "map_lab_run.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <glm/geometric.hpp>
#include <string>
#include <vector>

#include "lab_scenes.hpp"
#include "map_lab.hpp"
#include "nmbake/bake.hpp"
#include "scenes.hpp"

namespace nmbake::scenes {

namespace {

struct Row {
  std::string map, scene, method;
  double seconds = 0.0;
  MapError error;
  std::string unit;
  int rays = 0;
};

struct Case {
  std::string map, scene, method, unit;
  ScenePair pair;
  BakeOptions options;  // meshes and outputs set by run_case
  // The error of the baked EXR (the map's file) given the bake's report and low mesh.
  std::function<MapError(const Image&, const BakeReport&, const Mesh&)> score;
  int rays = 0;
};

Distance absolute(float value) { return {Distance::Kind::absolute, value}; }

RayOptions rays_of(const BakeReport& report) {
  RayOptions rays;
  rays.front = report.front;
  rays.back = report.back;
  return rays;
}

// The worst channel of a three-channel map against three answers.
MapError worst_channel(const Image& map, const ExpectedMap (&want)[3]) {
  MapError worst;
  for (int c = 0; c < 3; ++c) {
    const MapError e = score_map(map, c, want[c]);
    if (c == 0 || e.mean_abs > worst.mean_abs) worst = e;
  }
  return worst;
}

// Angle in degrees between the decoded texels of a normal-like map and
// unit vectors `want` (NaN x: not scored).
MapError angular_error(const Image& map, const std::vector<glm::dvec3>& want) {
  ExpectedMap zero;
  zero.width = map.width;
  zero.height = map.height;
  zero.value.assign(want.size(), std::nan(""));
  Image angles{map.width, map.height, 1, std::vector<float>(want.size(), 0.0f)};
  for (std::size_t t = 0; t < want.size(); ++t) {
    if (std::isnan(want[t].x)) continue;
    const float* p = map.pixels.data() + t * 3;
    const glm::dvec3 got = glm::normalize(glm::dvec3(2.0 * p[0] - 1.0, 2.0 * p[1] - 1.0, 2.0 * p[2] - 1.0));
    angles.pixels[t] =
        static_cast<float>(std::acos(std::clamp(glm::dot(got, want[t]), -1.0, 1.0)) * 180.0 / M_PI);
    zero.value[t] = 0.0;
  }
  return score_map(angles, 0, zero);
}

}  // namespace

int run_map_lab(const std::string& out_dir, int size) {
  namespace fs = std::filesystem;
  fs::create_directories(fs::path(out_dir) / "maps");
  std::vector<Case> cases;
  const auto base = [&](int samples) {
    BakeOptions o;
    o.width = o.height = size;
    o.samples = samples;
    o.padding = 0;
    return o;
  };
  {  // height
    HeightfieldParams hp;
    hp.high_cells = 512;
    SphereParams sp;
    sp.high_cells = 256;
    for (const std::string scene : {"heightfield", "sphere"}) {
      Case c{"height",
             scene,
             "4 spp",
             "scene units",
             scene == "sphere" ? make_displaced_sphere(sp) : make_heightfield(hp),
             base(4),
             nullptr};
      c.score = [scene, size](const Image& map, const BakeReport& r, const Mesh& low) {
        return score_map(map, 0, expected_height(scene, low, size, size, 4, rays_of(r)));
      };
      cases.push_back(std::move(c));
    }
  }
  {  // ambient occlusion and bent normals against the ray count
    struct Ao {
      std::string scene;
      ScenePair (*make)();
      float distance;
      std::function<double(const glm::dvec3&)> truth;
    };
    const std::vector<Ao> aos = {
        {"wall", make_wall_scene, kWallDistance,
         [](const glm::dvec3& p) { return wall_visibility(p.x, kWallDistance); }},
        {"bowl", [] { return make_bowl_scene(); }, kBowlDistance, [](const glm::dvec3&) { return 0.5; }},
        {"groove", make_groove_scene, kGrooveDistance,
         [](const glm::dvec3& p) { return groove_visibility(p.x); }},
    };
    for (const Ao& a : aos) {
      for (const int samples : {1, 4}) {
        for (const int rays : {16, 64, 256}) {
          if (samples == 4 && rays != 64) continue;
          Case c{"ao",         a.scene,  std::to_string(rays) + " rays, " + std::to_string(samples) + " spp",
                 "visibility", a.make(), base(samples),
                 nullptr,      rays};
          c.options.rays.front = c.options.rays.back = absolute(0.05f);
          c.options.ao_distance = absolute(a.distance);
          c.options.ao_rays = rays;
          c.score = [a, size, samples](const Image& map, const BakeReport&, const Mesh& low) {
            return score_map(map, 0, expected_from_low_points(low, size, size, samples, a.truth));
          };
          cases.push_back(std::move(c));
          if (a.scene != "groove" || samples != 1) continue;
          Case b{"bent-normal", a.scene, std::to_string(rays) + " rays, 1 spp", "degrees", a.make(), base(1),
                 nullptr,       rays};
          b.options.rays.front = b.options.rays.back = absolute(0.05f);
          b.options.ao_distance = absolute(a.distance);
          b.options.ao_rays = rays;
          b.score = [size](const Image& map, const BakeReport&, const Mesh& low) {
            ExpectedMap xs =
                expected_from_low_points(low, size, size, 1, [](const glm::dvec3& p) { return p.x; });
            std::vector<glm::dvec3> want(xs.value.size(), glm::dvec3(std::nan("")));
            for (std::size_t t = 0; t < want.size(); ++t) {
              if (!std::isnan(xs.value[t])) want[t] = groove_bent_normal(xs.value[t]);
            }
            return angular_error(map, want);
          };
          cases.push_back(std::move(b));
        }
      }
    }
  }
  {  // curvature
    for (const bool analytic : {true, false}) {
      SphereParams sp;
      sp.amplitude = 0.0f;
      sp.high_cells = 128;
      TorusParams tp;
      tp.amplitude = 0.0f;
      tp.high_cells = 128;
      for (const std::string scene : {"sphere", "torus"}) {
        Case c{"curvature",
               scene,
               analytic ? "analytic normals" : "computed normals",
               "1/scene units",
               scene == "sphere" ? make_displaced_sphere(sp) : make_torus(tp),
               base(4),
               nullptr};
        if (!analytic) c.pair.high.normals.clear();
        c.score = [scene, size](const Image& map, const BakeReport& r, const Mesh& low) {
          return score_map(map, 0, expected_curvature(scene, low, size, size, 4, rays_of(r)));
        };
        cases.push_back(std::move(c));
      }
    }
  }
  {  // thickness
    SphereParams sp;
    sp.amplitude = 0.0f;
    sp.high_cells = 128;
    for (const std::string scene : {"slab", "sphere"}) {
      Case c{"thickness",
             scene,
             "16 rays, 4 spp",
             "scene units",
             scene == "slab" ? make_slab_scene() : make_displaced_sphere(sp),
             base(4),
             nullptr};
      c.options.rays.front = c.options.rays.back = absolute(0.05f);
      c.options.thickness_distance = absolute(3.0f);
      c.score = [scene, size](const Image& map, const BakeReport&, const Mesh& low) {
        return score_map(map, 0, expected_from_low_points(low, size, size, 4, [&](const glm::dvec3& p) {
                           if (scene == "sphere") return sphere_thickness(1.0);
                           const bool inside = p.x > 0.05 && p.x < 0.95 && p.y > 0.05 && p.y < 0.95;
                           return inside ? static_cast<double>(kSlabThickness) : std::nan("");
                         }));
      };
      cases.push_back(std::move(c));
    }
  }
  {  // position: the analytic hit point in the high mesh's box
    SphereParams sp;
    sp.high_cells = 256;
    Case c{"position", "sphere", "4 spp", "box fraction (worst axis)", make_displaced_sphere(sp),
           base(4),    nullptr};
    const Bounds box = compute_bounds(c.pair.high);
    c.score = [box, size](const Image& map, const BakeReport& r, const Mesh& low) {
      ExpectedMap want[3];
      for (int a = 0; a < 3; ++a) {
        want[a] = expected_at_true_hits("sphere", low, size, size, 4, rays_of(r), [&](const glm::dvec3& hit) {
          return (hit[a] - box.min[a]) / (static_cast<double>(box.max[a]) - box.min[a]);
        });
      }
      return worst_channel(map, want);
    };
    cases.push_back(std::move(c));
  }

  std::vector<Row> rows;
  for (Case& c : cases) {
    // One folder per scene as the case builds it (the sphere of the height
    // map is displaced, the curvature's is not).
    std::string name = c.map + "_" + c.scene;
    if (c.map == "curvature") name += c.method == "analytic normals" ? "_analytic" : "_computed";
    if (c.map == "bent-normal") name = "ao_" + c.scene;
    const fs::path dir = fs::path(out_dir) / "maps" / name;
    fs::create_directories(dir);
    const std::string low_path = (dir / "low.obj").string(), high_path = (dir / "high.ply").string();
    if (!fs::exists(low_path) || !fs::exists(high_path)) {
      if (!save_mesh(low_path, c.pair.low) || !save_mesh(high_path, c.pair.high)) {
        std::fprintf(stderr, "nmbake-gen: cannot write %s\n", dir.string().c_str());
        return 2;
      }
    }
    BakeOptions o = c.options;
    o.low_path = low_path;
    o.high_paths = {high_path};
    MapKind map = MapKind::normal;
    parse_word(c.map, map);
    o.maps = {map};
    const std::string map_file =
        (dir / (c.map + "_" + std::to_string(c.rays) + "_" + std::to_string(o.samples) + ".exr")).string();
    o.outputs = {{map_file, PixelFormat::exr_float}};
    BakeReport report;
    const auto begin = std::chrono::steady_clock::now();
    const Status s = bake(o, report);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();
    if (!s) {
      std::fprintf(stderr, "nmbake-gen: %s %s: %s\n", c.map.c_str(), c.scene.c_str(), s.message().c_str());
      return 3;
    }
    Image image;
    Mesh low;
    LoadStats ls;
    MeshStats ms;
    if (!read_image(map_file, image) || !load_mesh(low_path, LoadOptions{true, true}, low, ls)) return 3;
    prepare_low_normals(low, ms);
    Row row{c.map, c.scene, c.method, seconds, c.score(image, report, low), c.unit, c.rays};
    std::printf("%-12s %-12s %-20s %6.2f s  %s\n", row.map.c_str(), row.scene.c_str(), row.method.c_str(),
                seconds, row.error.to_text().c_str());
    std::fflush(stdout);
    rows.push_back(row);
  }

  std::ofstream csv(fs::path(out_dir) / "maps_lab.csv");
  csv << "map,scene,method,rays,seconds,texels,mean_abs,bias,p99,max,unit\n";
  std::ofstream md(fs::path(out_dir) / "maps_lab.md");
  md << "| map | scene | method | time s | texels | mean abs error | bias | p99 | max | unit |\n"
        "|---|---|---|---:|---:|---:|---:|---:|---:|---|\n";
  char line[512];
  for (const Row& r : rows) {
    std::snprintf(line, sizeof line, "%s,%s,\"%s\",%d,%.4f,%zu,%.3g,%.3g,%.3g,%.3g,\"%s\"\n", r.map.c_str(),
                  r.scene.c_str(), r.method.c_str(), r.rays, r.seconds, r.error.texels, r.error.mean_abs,
                  r.error.mean_signed, r.error.p99, r.error.max, r.unit.c_str());
    csv << line;
    std::snprintf(line, sizeof line, "| %s | %s | %s | %.2f | %zu | %.2g | %+.1e | %.2g | %.2g | %s |\n",
                  r.map.c_str(), r.scene.c_str(), r.method.c_str(), r.seconds, r.error.texels,
                  r.error.mean_abs, r.error.mean_signed, r.error.p99, r.error.max, r.unit.c_str());
    md << line;
  }
  return csv && md ? 0 : 2;
}

}  // namespace nmbake::scenes
