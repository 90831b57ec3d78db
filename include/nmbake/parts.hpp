// Bake groups: which high triangles a low triangle's rays may hit
// (DESIGN.md, "Growing the pipeline": parts).
//
// A mesh file keeps its parts (mesh.hpp MeshPart: OBJ `o`/`g`, glTF nodes,
// FBX models). Parts become groups in one of three ways:
//   * explicit groups (job files: [[bake.group]] low = [...] high = [...]):
//     every listed name must be a part of its file;
//   * by name, as Substance's "match by mesh name" does: a low part
//     `X<low suffix>` is baked against the high parts `X<high suffix>`,
//     `X<high suffix>_N` and `X<high suffix>.N` (N digits: Blender's
//     duplicates, numbered exports). Suffixes are compared without regard to
//     case (`_low`, `_LOW`, `_Low`); the base name X exactly. Defaults:
//     `_low`, `_high`;
//   * none: one group, every low triangle against every high triangle
//     (today's behaviour, and what happens when nothing is named).
// With MatchMode::automatic (the default) names are matched when at least one
// low part ends in the low suffix, else there is one group.
// A low part that matches nothing is an error that lists every such part,
// unless Unmatched::all: then all of them form one more group, baked against
// every high part no other group uses. A high part no group uses is ignored
// (its rays would bleed) and listed in the report.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "nmbake/common.hpp"
#include "nmbake/mesh.hpp"
#include "nmbake/words.hpp"

namespace nmbake {

enum class MatchMode : std::uint8_t { automatic, name, off };
inline constexpr Word<MatchMode> kMatchModeWords[] = {
    {"auto", MatchMode::automatic, "by name when a low part ends in the low suffix"},
    {"name", MatchMode::name, "by name, always"},
    {"off", MatchMode::off, "every low triangle against every high triangle"},
};
NMBAKE_WORDS(MatchMode, kMatchModeWords)

enum class Unmatched : std::uint8_t { error, all };
inline constexpr Word<Unmatched> kUnmatchedWords[] = {
    {"error", Unmatched::error, "a low part with no high match is an error"},
    {"all", Unmatched::all, "bake it against every unused high part"},
};
NMBAKE_WORDS(Unmatched, kUnmatchedWords)

// One explicit group of a job file: part names of the low and high files.
struct GroupSpec {
  std::string name;  // for messages and the report; may be empty
  std::vector<std::string> low;
  std::vector<std::string> high;
};

struct MatchOptions {
  MatchMode mode = MatchMode::automatic;
  std::string low_suffix = "_low";
  std::string high_suffix = "_high";
  std::string cage_suffix = "_cage";
  Unmatched unmatched = Unmatched::error;
  std::vector<GroupSpec> groups;  // non-empty: explicit groups, names are not matched
};

// The result: empty `groups` means one group of everything.
struct BakeGroup {
  std::string name;                    // base name, explicit name, or "(unmatched)"
  std::vector<std::string> low_parts;  // distinct part names, in file order
  std::vector<std::string> high_parts;
  std::uint64_t low_triangles = 0;
  std::uint64_t high_triangles = 0;
};

struct BakeGroups {
  std::vector<BakeGroup> groups;
  std::vector<std::uint32_t> low_group;  // per low triangle (empty with no groups)
  // Per group, the high triangles it may hit, ascending (a part in two
  // explicit groups is in both).
  std::vector<std::vector<std::uint32_t>> high_triangles;
  std::vector<std::string> unused_high_parts;  // in no group: never hit

  bool grouped() const { return !groups.empty(); }
};

// The part of match_parts() that needs the low mesh only (its part names):
// a name in an explicit group that is not a low part, a low part in two
// explicit groups, MatchMode::name with no low part in the low suffix.
// bad_input naming the low file, as match_parts() words it. A job checks
// this for every bake before the first one runs (low meshes are small; a
// high mesh is read once, when its bake runs).
Status check_low_parts(const Mesh& low, const MatchOptions& options, const std::string& low_path);

// Matches the parts of `low` and `high` (paths for messages). bad_input on:
// a low part matching nothing (Unmatched::error; all such parts listed), a
// group with no high triangles, a name in an explicit group that is not a
// part of its file, a low part in two explicit groups, MatchMode::name with
// no named low part.
Status match_parts(const Mesh& low, const Mesh& high, const MatchOptions& options,
                   const std::string& low_path, const std::string& high_path, BakeGroups& out);

// A cage file with named parts is put in the low mesh's triangle order:
// low part `X<low suffix>` (or any low part named N) takes the cage part
// `X<cage suffix>` (or the cage part named N), the k-th range of a name the
// k-th range, and their triangle counts must agree. A cage without names,
// or a low mesh without parts, is left as it is (corner order, as before).
// bad_input naming the cage file and the part on a missing or extra part or
// a count that differs.
Status order_cage_by_parts(const Mesh& low, const MatchOptions& options, const std::string& cage_path,
                           Mesh& cage);

// Keeps only the high triangles some group uses, group by group: group g's
// triangles become [first[g], first[g + 1]) of the returned indices (a
// triangle in two groups appears twice). `first` gets group count + 1
// entries. Vertices are unchanged.
std::vector<std::uint32_t> group_high_indices(const Mesh& high, const BakeGroups& groups,
                                              std::vector<std::uint32_t>& first);

}  // namespace nmbake
