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

// Whether a cache folder can take entries: creates DIR (and its parents)
// when missing and makes and removes a scratch folder in it. io naming DIR
// and the reason when it is not a folder or cannot be written. Called
// before a bake, so that a cache the bake could not be stored in is an
// exit 2 with nothing written rather than a failure after the bake.
Status check_cache_dir(const std::string& dir);

// What cache_fetch found. `hit`: the maps and the report were served.
// `bad_entry` (not hit): DIR/<key> exists but was not served, and why (a
// file missing, of another size or checksum, not a regular file, a manifest
// of the wrong shape, ...): the caller warns, bakes, and stores with
// `replace`. Neither: no entry.
struct CacheLookup {
  bool hit = false;
  std::string bad_entry;
};

// When DIR/<key> holds a whole entry: copies its maps to the paths
// `options.outputs` names (UDIM tiles as the bake made them) and its report,
// marked "cached": true with the new paths, to `report_path` (if not
// empty). `written` gets the maps' paths.
//
// The entry is verified, not trusted: only regular files directly inside
// it are read (openat with O_NOFOLLOW; a name holding `/`, or `.` or `..`,
// is refused), each of the size its manifest records (bounded by what a map
// of the options' size can take) and of the XXH3-64 recorded when it was
// stored, checked on the very bytes copied. Every map goes to a temporary
// file beside its destination and is renamed only when all of them are
// verified: a bad entry writes nothing. An error Status is a failure to
// write a destination, never a bad entry.
Status cache_fetch(const std::string& dir, const BakeKey& key, const BakeOptions& options,
                   const std::string& report_path, CacheLookup& lookup, std::vector<std::string>& written);

// Stores the maps a finished bake wrote (report.tiles[].outputs, in the
// order of options.outputs) and `report_json` under the key, with each
// file's size and checksum in the manifest. An entry that is already there
// is kept, unless `replace` (cache_fetch found it bad): it is then moved
// aside, the new one renamed into place and the old removed.
Status cache_store(const std::string& dir, const BakeKey& key, const BakeOptions& options,
                   const BakeReport& report, const std::string& report_json, bool replace = false);

}  // namespace nmbake
