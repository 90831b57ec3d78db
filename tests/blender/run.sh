#!/usr/bin/env bash
# ctest's Blender.AddOnHeavy: packs the add-on (tools/blender-addon), then runs
# addon_test.py in a headless Blender with the built nmbake.
# Usage: run.sh NMBAKE SOURCE_DIR WORK_DIR. Exit 77 (skipped) without blender.
set -euo pipefail
nmbake=$1 source_dir=$2 work=$3
if ! command -v blender >/dev/null 2>&1; then
  echo "skipped: blender not found on PATH (tools/setup installs it)"
  exit 77
fi
rm -rf "$work" && mkdir -p "$work/scripts"
python3 "$source_dir/tools/blender-addon" "$work/nmbake_blender.zip" >/dev/null
# The add-on is installed into a scripts folder of the test's own, not the user's.
BLENDER_USER_SCRIPTS="$work/scripts" BLENDER_USER_CONFIG="$work/config" NMBAKE="$nmbake" \
  blender -b --factory-startup --python-exit-code 1 \
  --python "$source_dir/tests/blender/addon_test.py" -- "$work/nmbake_blender.zip" "$nmbake" "$work"
