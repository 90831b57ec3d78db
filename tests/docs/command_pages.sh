#!/usr/bin/env bash
# The committed command pages (docs/reference/commands/) are what
# `nmbake docs --markdown` writes today: regenerated into a temporary folder
# and compared, so a flag added to a command cannot leave its page behind
# (ctest Docs.CommandPagesCurrent):
#   tests/docs/command_pages.sh NMBAKE SOURCE_ROOT
set -euo pipefail
nmbake=$1
root=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$nmbake" docs --markdown "$tmp/commands"
if ! diff -ru "$root/docs/reference/commands" "$tmp/commands"; then
  echo "FAIL: docs/reference/commands differs from nmbake docs --markdown: run" >&2
  echo "  build/nmbake docs --markdown docs/reference/commands" >&2
  exit 1
fi
echo "command pages: $(ls "$tmp/commands" | wc -l) pages, as nmbake docs --markdown writes them"
