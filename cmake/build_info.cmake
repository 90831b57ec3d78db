# Writes OUT (a C++ file defining nmbake::cli::kBuildCommit) from the source
# tree's git commit, at every build; the file is rewritten only when the
# commit changes, so a build without changes recompiles nothing. Outside a git
# checkout (a source tarball) the commit is NMBAKE_COMMIT from the environment,
# else "unknown".
if(DEFINED ENV{NMBAKE_COMMIT})
  set(commit "$ENV{NMBAKE_COMMIT}")
else()
  execute_process(COMMAND git -C "${SOURCE_DIR}" rev-parse --short=12 HEAD
    OUTPUT_VARIABLE commit OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET RESULT_VARIABLE failed)
  if(failed OR commit STREQUAL "")
    set(commit "unknown")
  else()
    execute_process(COMMAND git -C "${SOURCE_DIR}" status --porcelain --untracked-files=no
      OUTPUT_VARIABLE changes OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET)
    if(NOT changes STREQUAL "")
      string(APPEND commit "+changes")
    endif()
  endif()
endif()
set(text "// Written by cmake/build_info.cmake at build time.\nnamespace nmbake::cli {\nextern const char* const kBuildCommit;\nconst char* const kBuildCommit = \"${commit}\";\n}  // namespace nmbake::cli\n")
if(EXISTS "${OUT}")
  file(READ "${OUT}" old)
else()
  set(old "")
endif()
if(NOT old STREQUAL text)
  file(WRITE "${OUT}" "${text}")
endif()
