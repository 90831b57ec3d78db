// nmbake-gen maplab (map_lab_run.cpp).
#pragma once

#include <string>

namespace nmbake::scenes {

// Bakes and scores every map of the map set on its analytic scenes at
// size x size; writes OUT/maps_lab.csv, OUT/maps_lab.md and the bakes under
// OUT/maps/. Returns the exit code.
int run_map_lab(const std::string& out_dir, int size);

}  // namespace nmbake::scenes
