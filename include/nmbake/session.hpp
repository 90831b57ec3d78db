// A live bake session (`nmbake serve`, README "Live sessions"): what it keeps
// between requests, and how a request's bake becomes BakeOptions.
//
// The cache holds the high side of recent bakes (bake.hpp: LoadedHigh, the
// high mesh as read; BuiltHigh, its BVH and the map set's data of it) under
// bake()'s keys, which name the high files' bytes (XXH3-64 of every byte,
// with the path and size: a file rewritten with other bytes is another
// mesh, whatever its date) and the options that shaped them. Entries are
// dropped least recently used first when their bytes pass the budget; an
// entry a running bake holds stays alive until that bake ends (shared_ptr).
#pragma once

#include <cstdint>
#include <list>
#include <memory>
#include <nlohmann/json_fwd.hpp>
#include <string>

#include "nmbake/bake.hpp"
#include "nmbake/common.hpp"
#include "nmbake/job.hpp"

namespace nmbake {

struct HighCacheStats {
  std::uint64_t entries = 0;
  std::uint64_t bytes = 0;
  std::uint64_t budget = 0;
  std::uint64_t evictions = 0;
};

// Bytes an entry is counted for: its arrays, and for a BuiltHigh 64 bytes a
// triangle of BVH (DESIGN.md: Embree's medium BVH; the low and compact ones
// take less).
std::uint64_t entry_bytes(const LoadedHigh& high);
std::uint64_t entry_bytes(const BuiltHigh& high);

// Not thread-safe: one bake at a time uses it (stats() from another thread
// goes through the caller's own lock).
class HighCache final : public HighStore {
 public:
  explicit HighCache(std::uint64_t budget_bytes) { stats_.budget = budget_bytes; }
  std::shared_ptr<const LoadedHigh> find_loaded(const std::string& key) override;
  void keep_loaded(const std::string& key, std::shared_ptr<const LoadedHigh> high) override;
  std::shared_ptr<const BuiltHigh> find_built(const std::string& key) override;
  void keep_built(const std::string& key, std::shared_ptr<const BuiltHigh> high) override;
  HighCacheStats stats() const { return stats_; }

 private:
  struct Entry {
    std::string key;
    std::shared_ptr<const LoadedHigh> loaded;  // one of the two
    std::shared_ptr<const BuiltHigh> built;
    std::uint64_t bytes = 0;
  };
  std::list<Entry>::iterator find(const std::string& key);
  void keep(Entry entry);
  std::list<Entry> entries_;  // most recently used first
  HighCacheStats stats_;
};

// The bake of a live request: `bake` holds the keys of a job file's [[bake]]
// table (job.hpp: the option table's keys, and low, high, cage, outputs,
// name, report, group) as JSON values; relative paths resolve against
// `folder`. bad_input naming the key ("bake.samples: expected ...",
// "bake: unknown key \"smaples\""), or what is missing. The values are
// checked as a job file's are (validate_option_values()); the files when the
// bake runs.
Status request_bake_job(const nlohmann::json& bake, const std::string& folder, BakeJob& job);

}  // namespace nmbake
