// Private to src/bake/: what the pipeline's pieces share (bake.cpp,
// adaptive_rows.cpp): the stage timer that fills the report's times and
// drives the progress listener, and the prepared inputs every UDIM tile reads.
#pragma once

#include <sys/resource.h>

#include <chrono>
#include <cstdint>

#include "nmbake/bake.hpp"
#include "nmbake/bake_options.hpp"
#include "nmbake/bake_report.hpp"
#include "nmbake/maps.hpp"
#include "nmbake/mesh.hpp"
#include "nmbake/trace.hpp"

namespace nmbake::detail {

using Clock = std::chrono::steady_clock;

inline std::uint64_t peak_rss_bytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<std::uint64_t>(usage.ru_maxrss) * 1024u;
}

class StageTimer {
 public:
  StageTimer(BakeReport& report, const ProgressFn& progress) : report_(report), progress_(progress) {}
  void start(const char* name) {
    name_ = name;
    begin_ = Clock::now();
    if (progress_) progress_(name_, 0.0);
  }
  // A stage run several times (once per band) adds up under one name.
  void stop(bool report_done = true) {
    const double seconds = std::chrono::duration<double>(Clock::now() - begin_).count();
    for (StageTime& st : report_.stages) {
      if (st.name == name_) {
        st.seconds += seconds;
        if (progress_ && report_done) progress_(name_, 1.0);
        return;
      }
    }
    report_.stages.push_back({name_, seconds});
    if (progress_ && report_done) progress_(name_, 1.0);
  }
  void start_quietly(const char* name) {
    name_ = name;
    begin_ = Clock::now();
  }

 private:
  BakeReport& report_;
  const ProgressFn& progress_;
  const char* name_ = "";
  Clock::time_point begin_;
};

// What every UDIM tile of a bake shares: the prepared meshes, the scene and
// the rays.
struct Prepared {
  const BakeOptions& options;
  const Mesh& high;
  const HighScene& scene;
  const RayOptions& rays;
  MapSettings maps;  // the map set, with the normal map's encode options
};

}  // namespace nmbake::detail
