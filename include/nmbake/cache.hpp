// A content-addressed cache of finished bakes, keyed by the bake key
// (task.hpp): `--cache DIR`, `cache = "DIR"` in job files, or NMBAKE_CACHE.
//
// An entry is a folder DIR/<key>/ holding copies of the maps a bake wrote
// (every output, every UDIM tile), its report and a manifest. It is built
// under a temporary name and renamed into place, so it appears whole or not
// at all: two processes baking the same key on a shared file system never
// leave a torn entry (the second rename finds the first entry and its own
// is dropped). A fetch copies each map to a temporary name beside its
// destination and renames it there, as every writer of nmbake does.
#pragma once

#include <string>
#include <vector>

#include "nmbake/bake_options.hpp"
#include "nmbake/bake_report.hpp"
#include "nmbake/task.hpp"

namespace nmbake {

// The folder to use: `flag` if set, else $NMBAKE_CACHE, else "" (no cache).
std::string resolve_cache_dir(const std::string& flag);

// When DIR/<key> exists: copies its maps to the paths `options.outputs`
// names (UDIM tiles as the bake made them) and its report, marked
// "cached": true with the new paths, to `report_path` (if not empty);
// `hit` is set. `written` gets the maps' paths. A missing entry is no error.
Status cache_fetch(const std::string& dir, const BakeKey& key, const BakeOptions& options,
                   const std::string& report_path, bool& hit, std::vector<std::string>& written);

// Stores the maps a finished bake wrote (report.tiles[].outputs, in the
// order of options.outputs) and `report_json` under the key. An entry that
// is already there is kept.
Status cache_store(const std::string& dir, const BakeKey& key, const BakeOptions& options, const BakeReport& report,
                   const std::string& report_json);

}  // namespace nmbake
