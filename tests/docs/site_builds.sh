#!/usr/bin/env bash
# The documentation site builds with `mkdocs build --strict` (broken links,
# missing images and pages outside the nav fail it), into the build folder,
# never into the source tree (ctest Docs.SiteBuilds):
#   tests/docs/site_builds.sh SOURCE_ROOT BUILD_DIR
# Without Debian's mkdocs (tools/setup installs it): exit 77, ctest SKIP.
set -euo pipefail
root=$1
build=$2
if [ ! -x /usr/bin/mkdocs ]; then
  echo "SKIP: /usr/bin/mkdocs is missing (tools/setup installs Debian's mkdocs)"
  exit 77
fi
# Debian's mkdocs runs on Debian's python3 whatever python3 is first on PATH.
/usr/bin/mkdocs build --strict --quiet -f "$root/mkdocs.yml" -d "$build/site"
pages=$(find "$root/docs" -name '*.md' | wc -l)
[ -f "$build/site/index.html" ] || { echo "FAIL: no index.html in $build/site" >&2; exit 1; }
[ -f "$build/site/reference/report.html" ] || { echo "FAIL: no reference/report.html" >&2; exit 1; }
echo "site: $pages pages built with --strict into $build/site"
