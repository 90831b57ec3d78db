// Private to src/bake/: what bake() shares with the option checks
// (validate.cpp): the distance check it runs once the low mesh is loaded,
// and how it loads the low mesh (check_bake_low_mesh() loads it the same
// way, so a job's early check sees the bake's own errors).
#pragma once

#include "nmbake/bake_options.hpp"
#include "nmbake/common.hpp"
#include "nmbake/load.hpp"
#include "nmbake/trace.hpp"

namespace nmbake::detail {

// A resolved distance against the low mesh's diagonal (kMaxDistanceDiagonals);
// `name` ("front", "back") starts the message.
Status check_distance(const char* name, const Distance& d, float diagonal);

LoadOptions low_load_options(const BakeOptions& o);
// Whether an output path holds <UDIM>: one map per UV tile.
bool bakes_udim_tiles(const BakeOptions& o);
// Some output or pack holds <SET>: a map set per low material (sets.hpp).
bool bakes_texture_sets(const BakeOptions& o);

}  // namespace nmbake::detail
