// Hard-edged and concave scenes for the accuracy lab's appearance error
// (appearance.hpp): a low mesh with split normals (hard edges) over a high
// mesh whose edges are rounded, chamfered or carved. Each knows its true
// surface as an exact signed distance (or a field with the right zero set
// and gradient direction) and its analytic normal, so the analytic
// evaluator (eval.hpp) scores them too. Pure functions of their
// parameters: the same meshes, bit for bit, on every machine.
//
//   bowl      a dish turned around the y axis: a flat floor meeting a conical
//             inner wall at a concave hard edge, a flat rim, a conical outer
//             wall and a foot; the high mesh rounds every edge (fillets);
//   cylinder  a cylinder whose caps meet the side at hard edges in the low
//             mesh and at 45-degree chamfers in the high mesh;
//   panel     a slab (hard-edged box, 2 x 0.3 x 2) whose top face is carved
//             with pockets: a rounded rectangle, a round pocket, a groove
//             and a slot close to two edges (within a ray's reach of the
//             hard edge), and a small conical dimple deeper (0.11) than
//             everything else (0.05), deeper than the automatic ray distance.
// The bevelled boxes of several radii are lab_scenes.hpp's box.
#pragma once

#include <glm/ext/vector_double2.hpp>
#include <glm/ext/vector_double3.hpp>
#include <string>
#include <vector>

#include "scenes.hpp"

namespace nmbake::scenes {

// --- Surfaces of revolution ---------------------------------------------------
// A profile in the (rho, y) half-plane (rho >= 0) turned around the y axis:
// points p_0 .. p_n, p_0 and p_n on the axis (rho = 0), joined by straight
// segments; with the axis they enclose the solid. Every interior point is a
// corner: a hard edge in the low mesh (split normals) unless `low_smooth`;
// in the high mesh rounded by a fillet of radius `fillet` (an arc tangent
// to both segments), or cut by a chamfer whose ends lie `chamfer` from the
// corner along each segment, or left sharp (split normals there too).
struct ProfileCorner {
  double rho = 0.0, y = 0.0;
  double fillet = 0.0, chamfer = 0.0;
  bool low_smooth = false;
};

struct RevolveParams {
  std::vector<ProfileCorner> profile;
  int low_segments = 24;     // around the axis (a multiple of 4: four UV charts per band)
  int high_segments = 720;   // around the axis
  double high_step = 0.004;  // along the profile, scene units (arcs: also at most 2 degrees a step)
};
RevolveParams bowl_params();
RevolveParams cylinder_params();

// The high profile as a chain of segments and arcs, with its exact signed
// distance (< 0 inside the solid) and outward normal in the half-plane.
class RevolveProfile {
 public:
  explicit RevolveProfile(const std::vector<ProfileCorner>& corners);
  double signed_distance(const glm::dvec2& q, glm::dvec2* normal) const;
  struct Element {
    bool arc = false;
    glm::dvec2 a{0.0}, b{0.0};  // ends
    glm::dvec2 centre{0.0};
    double radius = 0.0, angle0 = 0.0, sweep = 0.0;  // arc: centre + radius (cos, sin)(angle0 + s sweep)
    double outward = 1.0;    // arc: +1 the normal points away from the centre, -1 towards it
    glm::dvec2 normal{0.0};  // segment: outward unit normal
    double length = 0.0;
    glm::dvec2 point(double s) const;
    glm::dvec2 normal_at(double s) const;
  };
  const std::vector<Element>& elements() const { return elements_; }

 private:
  std::vector<Element> elements_;
};
double revolve_field(const RevolveProfile& profile, const glm::dvec3& x);
glm::dvec3 revolve_normal(const RevolveProfile& profile, const glm::dvec3& x);
ScenePair make_revolved(const RevolveParams& p);

// --- Panel ---------------------------------------------------------------------
// The slab [-half, half] x [bottom, top] x [-half, half] (y up). The top face
// is the heightfield y = top - depth(x, z), depth = sum over pockets of
// pocket.depth * smoothstep(0, 1, -s / pocket.wall), s the signed distance
// (< 0 inside) to the pocket's rounded rectangle in the (x, z) plane: walls
// that leave the top and reach the floor with zero slope. Pockets do not
// overlap and stay off the border, so the top meets the sides at y = top.
struct PanelPocket {
  double x = 0.0, z = 0.0;            // centre
  double half_x = 0.0, half_z = 0.0;  // half sizes; a circle when both equal `radius`
  double radius = 0.0;                // corner radius
  double depth = 0.0, wall = 0.0;
};
struct PanelParams {
  double half = 1.0, top = 0.15, bottom = -0.15;
  std::vector<PanelPocket> pockets;
  int low_cells = 4;     // quads per side of the low top and bottom faces
  int high_cells = 400;  // quads per side of the high top and bottom faces
};
PanelParams panel_params();
// Depth and its gradient (d/dx, d/dz) at (x, z).
double panel_depth(const PanelParams& p, double x, double z, double* ddx, double* ddz);
double panel_field(const PanelParams& p, const glm::dvec3& x);
glm::dvec3 panel_normal(const PanelParams& p, const glm::dvec3& x);
ScenePair make_panel(const PanelParams& p);

// --- Names ---------------------------------------------------------------------
// The bevel radius of the lab's box scenes: "box" (0.2), "box_r0.05",
// "box_r0.1", "box_r0.4"; negative for any other name.
double lab_box_bevel(const std::string& scene);
// Every scene of this file and the box variants, in lab order.
const std::vector<std::string>& hard_scene_names();
// Generates one of hard_scene_names() (the boxes with make_box); false for
// another name.
bool make_hard_scene(const std::string& scene, ScenePair& out);

}  // namespace nmbake::scenes
