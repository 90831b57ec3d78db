#!/usr/bin/env bash
# The manual pages, the bash completion and --version (ctest Docs.*):
#   tests/docs_test.sh NMBAKE BUILD_DIR
# The pages and the completion are the build's (nmbake docs, at build time);
# the checks: every command has a page, `man --warnings` prints nothing for
# any page, each page lists every flag of the command's --help, completion
# offers the commands, a command's flags and a flag's words, and --version
# names the commit and the libraries.
set -euo pipefail
nmbake=$1
build=$2
fail() { echo "FAIL: $*" >&2; exit 1; }

commands=$("$nmbake" --help | awk '/^Subcommands:/ {on = 1; next} on && NF {print $1}')
[ -n "$commands" ] || fail "no commands in nmbake --help"
for c in $commands; do
  page="$build/man/nmbake-$c.1.gz"
  [ -f "$page" ] || fail "no manual page for '$c' ($page)"
  if command -v man >/dev/null; then
    warnings=$(MANWIDTH=80 man --warnings -l "$page" 2>&1 >/dev/null || true)
    [ -z "$warnings" ] || fail "man --warnings on $page: $warnings"
  fi
  # Every flag --help lists is on the page (groff writes a flag's '-' as '\-').
  text=$(gzip -dc "$page" | sed 's/\\-/-/g')
  for flag in $("$nmbake" "$c" --help | grep -oE '^ +(-[a-z],)?--[a-z0-9-]+' | grep -oE -- '--[a-z0-9-]+'); do
    grep -qF -- "$flag" <<<"$text" || fail "nmbake-$c.1 lacks $flag"
  done
done
[ -f "$build/man/nmbake.1.gz" ] || fail "no nmbake.1"
echo "manual: $(echo $commands | wc -w) command pages and nmbake(1), man --warnings clean"

# Completion: the script as the package installs it, driven as bash would.
# shellcheck disable=SC1090
source "$build/completion/nmbake"
complete_words() {  # the words typed so far, the last one being completed
  COMP_WORDS=("$@")
  COMP_CWORD=$((${#COMP_WORDS[@]} - 1))
  COMPREPLY=()
  _nmbake
  echo "${COMPREPLY[*]}"
}
got=$(complete_words nmbake ba)
[ "$got" = "bake" ] || fail "completing 'nmbake ba' gave '$got', not 'bake'"
got=$(complete_words nmbake bake --spa)
[ "$got" = "--space" ] || fail "completing 'nmbake bake --spa' gave '$got'"
got=$(complete_words nmbake bake --space "")
[ "$got" = "tangent object" ] || fail "completing 'nmbake bake --space' gave '$got'"
got=$(complete_words nmbake -v bake --preset un)
[ "$got" = "unity unreal" ] || fail "completing 'nmbake bake --preset un' gave '$got'"
got=$(complete_words nmbake bake --progress "")
[ "$got" = "auto bar json none" ] || fail "completing 'nmbake bake --progress' gave '$got'"
got=$(complete_words nmbake bake --format exr-f)
[ "$got" = "exr-float exr-float-piz" ] || fail "completing 'nmbake bake --format exr-f' gave '$got'"
got=$(complete_words nmbake height2normal --border "")
[ "$got" = "clamp wrap" ] || fail "completing 'nmbake height2normal --border' gave '$got'"
got=$(complete_words nmbake preview --hi)
[ "$got" = "--high --hit" ] || fail "completing 'nmbake preview --hi' gave '$got'"
echo "completion: commands, flags and words complete"

version=$("$nmbake" --version)
echo "$version"
for name in "commit " "Embree " "OpenImageIO " "Assimp " "tinygltf " "oneTBB "; do
  grep -q "$name" <<<"$version" || fail "--version does not name '$name'"
done
grep -qE "OpenImageIO +[0-9]+\.[0-9]+\.[0-9]+ \(image module /" <<<"$version" || fail "--version: no OpenImageIO module"
echo "Docs: passed"
