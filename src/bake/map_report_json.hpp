// Private to the library: the map set's reports as JSON, the same in the
// bake report and the merge report.
#pragma once

#include <nlohmann/json.hpp>
#include <vector>

#include "nmbake/maps.hpp"

namespace nmbake::detail {

// [{"map", "tile", "outputs", then each figure by name}], in the set's order.
nlohmann::ordered_json map_reports_json(const std::vector<MapReport>& reports);

}  // namespace nmbake::detail
