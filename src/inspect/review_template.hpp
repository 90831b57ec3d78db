// The page template of `nmbake view` (src/inspect/view/viewer.html and
// viewer.js), compiled into the binary by CMake (src/inspect/view/embed.cmake
// writes review_template.cpp from them at build time).
#pragma once

namespace nmbake::review_detail {

extern const char* const kViewerHtml;  // with /*NMBAKE_THREE*/, /*NMBAKE_VIEWER*/, NMBAKE_CONFIG, NMBAKE_GLB
extern const char* const kViewerJs;

}  // namespace nmbake::review_detail
