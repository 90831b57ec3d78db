#!/usr/bin/env bash
# The farm test (issue 16): a plan run through a real one-node Slurm cluster.
# A job file of 5 bakes, two of them in 4 tiles (one a map set), is planned with
# `nmbake plan --slurm DIR --cache CACHE` and submitted with `submit.sh
# --wait` (the bake array, then the merge array chained with
# --dependency=afterok); every map must equal the one-machine bake byte for
# byte. Prints the job ids and states. Exit 77 (ctest: skipped, with the
# reason printed) only where Slurm cannot run here.
# Usage: slurm_plan.sh NMBAKE NMBAKE_GEN SOURCE_DIR
set -euo pipefail
nmbake=$1 gen=$2 src=$3
cluster="$src/tools/slurm/cluster"
if ! reason=$("$cluster" available 2>&1); then
  echo "SKIP: Slurm cannot run here: $reason"
  exit 77
fi
work=$(mktemp -d /tmp/nmbake-farm.XXXXXX)
slurm_dir="$work/c"  # short: the munge socket path must stay under 80 characters
cleanup() { "$cluster" stop "$slurm_dir" >/dev/null 2>&1 || true; rm -rf "$work"; }
trap cleanup EXIT
start_time=$(date +%s.%N)

# Two small scenes, five bakes; "big" and "bigmaps" (normal, height, AO and
# curvature) are the ones a plan tiles.
"$gen" sphere --out-dir "$work/s" --high-cells 96 --low-cells 4 >/dev/null
"$gen" torus --out-dir "$work/t" --high-cells 96 --low-cells 8 >/dev/null
cat >"$work/job.toml" <<TOML
[defaults]
size = 128
samples = 4
[[bake]]
name = "sphere"
low = "s/sphere_low.obj"
high = "s/sphere_high.ply"
outputs = ["out/sphere.png"]
[[bake]]
name = "torus"
low = "t/torus_low.obj"
high = "t/torus_high.ply"
outputs = ["out/torus.png", "out/torus.exr"]
[[bake]]
name = "object it's \$(touch marker) \`touch marker\` a | b: c"
low = "s/sphere_low.obj"
high = "s/sphere_high.ply"
space = "object"
samples = 1
outputs = ["out/object.png"]
[[bake]]
name = "big"
low = "t/torus_low.obj"
high = "t/torus_high.ply"
size = 300
padding = 40
outputs = ["out/big.png", "out/big.exr"]
report = "out/big.json"
[[bake]]
name = "bigmaps"
low = "t/torus_low.obj"
high = "t/torus_high.ply"
size = 300
maps = ["normal", "height", "ao", "curvature"]
ao_rays = 8
outputs = ["out/bigmaps_<MAP>.png", "out/bigmaps_<MAP>.exr"]
TOML
mkdir -p "$work/out"
# One machine, whole bakes: the reference.
"$nmbake" bake "$work/job.toml" -q
mv "$work/out" "$work/ref"
mkdir -p "$work/out"

# A plan folder with what sbatch's #SBATCH parser and --output pattern read
# specially (a space, '#', '%', a quote), and a bake name with what the
# array task's `bash -c` would run: the logs land where asked, nothing runs.
plan="$work/plan dir #%x \"q\""
"$nmbake" plan "$work/job.toml" --tiles 4 --tiles-min-size 300 --slurm "$plan" --cache "$work/cache"
started=$("$cluster" start "$slurm_dir") || { echo "FAIL: the one-node cluster did not start"; exit 1; }
eval "$started"
echo "cluster up: $SLURM_CONF"
if ! timeout 300 "$plan/submit.sh" --wait | tee "$work/submit.log"; then
  echo "FAIL: submit.sh --wait failed"
  for f in "$plan"/logs/*; do echo "== $f"; cat "$f"; done
  exit 1
fi
for id in $(grep -o 'job [0-9]*' "$work/submit.log" | cut -d' ' -f2); do
  scontrol -o show job "$id" | while read -r line; do
    for field in $line; do
      case $field in JobId=* | ArrayJobId=* | ArrayTaskId=* | JobName=* | JobState=* | ExitCode=*) printf '%s ' "$field" ;; esac
    done
    echo
  done
done
status=0
maps=()
for m in normal height ao curvature; do maps+=("bigmaps_$m.png" "bigmaps_$m.exr"); done
for f in sphere.png torus.png torus.exr object.png big.png big.exr "${maps[@]}"; do
  if cmp -s "$work/ref/$f" "$work/out/$f"; then
    echo "identical: $f ($(stat -c %s "$work/out/$f") bytes)"
  else
    echo "FAIL: $f differs from the one-machine bake"
    status=1
  fi
done
ls "$work"/out/big.png.tile-*-of-4 "$work"/out/bigmaps_normal.png.tile-*-of-4 >/dev/null ||
  { echo "FAIL: no tile files"; status=1; }
bake_id=$(grep -o 'bake array: job [0-9]*' "$work/submit.log" | cut -d' ' -f4)
logs=$(find "$plan/logs" -name "bake-${bake_id}_*.log" | wc -l)
echo "bake logs: $logs (one per array task)"
[ "$logs" -eq 11 ] || { echo "FAIL: expected 11 bake logs in $plan/logs"; status=1; }
if [ -n "$(find "$work" -name marker)" ]; then
  echo "FAIL: a bake name ran as a command (marker file)"
  status=1
fi
entries=$(find "$work/cache" -mindepth 1 -maxdepth 1 -type d | wc -l)
echo "cache entries: $entries (3 whole bakes; tiles are not cached)"
[ "$entries" -eq 3 ] || status=1
echo "farm test: $( [ $status = 0 ] && echo PASS || echo FAIL ) in $(awk -v a="$start_time" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }') s"
exit $status
