#!/usr/bin/env bash
# The Troubleshooting page's pictures (ctest Docs.TroubleshootingPicturesHeavy):
#   tests/troubleshooting_test.sh BUILD_DIR SOURCE_DIR
# Runs tools/troubleshooting-pictures into a temporary folder, checks that every
# picture docs/troubleshooting.md shows was made, and that each problem and its
# fix differ the way the page says, from the figures the tools print (preview
# error, miss share, diff statistics, report counters): not from the pixels of
# the committed pictures. Skipped (exit 77) without oiiotool.
set -euo pipefail
build=$1
src=$2
command -v oiiotool >/dev/null || { echo "skipped: oiiotool not found (Debian: openimageio-tools)"; exit 77; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
python3 "$src/tools/troubleshooting-pictures" --build "$build" --out "$tmp/pictures" --numbers "$tmp/numbers.json"
python3 - "$src/docs/troubleshooting.md" "$tmp/pictures" "$tmp/numbers.json" <<'EOF'
import json, os, re, sys
page, pictures, numbers = sys.argv[1], sys.argv[2], json.load(open(sys.argv[3]))
failures = []
def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        failures.append(what)

shown = re.findall(r"\]\(troubleshooting/([A-Za-z0-9_.-]+\.png)\)", open(page).read())
check(len(shown) == 9, f"the page shows 9 pictures ({len(shown)})")
for name in shown:
    path = os.path.join(pictures, name)
    check(os.path.isfile(path) and os.path.getsize(path) > 1000, f"{name} made")
    check(os.path.isfile(path) and os.path.getsize(path) < 60000, f"{name} under 60 KB")

def fig(symptom):
    return numbers[symptom]["problem"], numbers[symptom]["fix"]

bad, good = fig("waviness")
check(bad["appearance_mean_deg"] > good["appearance_mean_deg"], "waviness: appearance mean, averaged > banded")
check(bad["error_mean_deg"] > good["error_mean_deg"], "waviness: preview error mean, averaged > banded")
bad, good = fig("hard_edge_seams")
check(bad["error_mean_deg"] > 1.3 * good["error_mean_deg"], "seams: preview error mean, strip > 1.3 x split")
check(bad["error_max_deg"] > 2 * good["error_max_deg"], "seams: preview error max, strip > 2 x split")
bad, good = fig("part_bleeding")
check(bad["diff_to_exploded_mean_deg"] > 0.5, "bleeding: --match off differs from the exploded bake (> 0.5 deg mean)")
check(good["diff_to_exploded_mean_deg"] < 0.01, "bleeding: matched by name equals the exploded bake (< 0.01 deg mean)")
check(good["groups"] == 2 and bad["groups"] == 0, "bleeding: two bake groups by name, none with --match off")
bad, good = fig("holes_and_misses")
check(bad["miss_share"] > 0.05 and bad["misses"] > 0, "holes: short distances miss > 5% of the preview's rays")
check(good["miss_share"] == 0 and good["misses"] == 0, "holes: auto distances miss nothing")
bad, good = fig("skewed_details")
check(bad["appearance_mean_deg"] > 1.05 * good["appearance_mean_deg"], "skew: appearance mean, averaged > 1.05 x banded")
bad, good = fig("8bit_banding")
check(bad["longest_run"] > 2 * good["longest_run"], "banding: longest run, rounded > 2 x dithered")
check(bad["texels_in_runs_16"] > 3 * good["texels_in_runs_16"], "banding: texels in runs >= 16, rounded > 3 x dithered")
check(bad["block4_error_mean_deg"] > 2 * good["block4_error_mean_deg"], "banding: 4x4 mean error, rounded > 2 x dithered")
bad, good = fig("inverted_green")
check(bad["error_mean_deg"] > 10 * good["error_mean_deg"], "green: preview error mean, wrong > 10 x right")
bad, good = fig("mirrored_uvs")
check(bad["overlapping_samples"] > 0 and good["overlapping_samples"] == 0, "mirrored: overlap counted only when the halves share texels")
check(bad["error_mean_deg"] > 10 * good["error_mean_deg"], "mirrored: preview error mean, shared > 10 x own texels")
check(good["error_mean_deg"] < 0.05, "mirrored: a mirrored chart with its own texels bakes right (< 0.05 deg)")
bad, good = fig("nan_black_texels")
check(bad["zero_area_triangles"] >= 1 and bad["degenerate_uv_triangles"] >= 1, "nan: the broken triangles are counted")
check(bad["nan_texels"] == 0 and good["nan_texels"] == 0, "nan: no NaN in either EXR")
check(good["zero_area_triangles"] == 0 and good["degenerate_uv_triangles"] == 0, "nan: the clean low has no fallbacks")
if failures:
    sys.exit(f"{len(failures)} check(s) failed")
print("Troubleshooting pictures: passed")
EOF
