# Writes OUT, a C++ file defining nmbake::review_detail::kViewerHtml and
# kViewerJs from the files HTML and JS (cmake -DHTML=... -DJS=... -DOUT=... -P
# embed.cmake). The texts go in as raw string literals, split in pieces
# the compilers take.
function(nmbake_literal path out_var)
  file(READ "${path}" text)
  string(FIND "${text}" ")nmbv\"" bad)
  if(NOT bad EQUAL -1)
    message(FATAL_ERROR "${path} contains the literal's end marker")
  endif()
  set(result "")
  string(LENGTH "${text}" n)
  set(at 0)
  while(at LESS n)
    string(SUBSTRING "${text}" ${at} 8000 piece)
    string(APPEND result "R\"nmbv(${piece})nmbv\"\n")
    math(EXPR at "${at} + 8000")
  endwhile()
  set(${out_var} "${result}" PARENT_SCOPE)
endfunction()
nmbake_literal("${HTML}" html)
nmbake_literal("${JS}" js)
file(WRITE "${OUT}.tmp" "// Generated from src/inspect/view/ by embed.cmake: do not edit.\n#include \"inspect/review_template.hpp\"\n\nnamespace nmbake::review_detail {\n\nconst char* const kViewerHtml =\n${html};\nconst char* const kViewerJs =\n${js};\n\n}  // namespace nmbake::review_detail\n")
file(RENAME "${OUT}.tmp" "${OUT}")
