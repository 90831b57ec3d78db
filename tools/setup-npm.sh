#!/bin/sh
# Installs the node packages of the tests, each with its committed
# package-lock.json: the one the tangents test compares against (the npm
# package `mikktspace`, a WASM build of the MikkTSpace reference) into
# tests/mikktspace_ref/node_modules, and the Khronos glTF validator (npm
# `gltf-validator`) the view test runs on its .glb files into
# tests/gltf_validator/node_modules. Needs node and npm.
set -eu

here=$(cd "$(dirname "$0")/.." && pwd)
ref_dir="$here/tests/mikktspace_ref"

if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
  echo "setup-npm.sh: node and npm are needed (Debian: apt-get install nodejs npm)" >&2
  exit 1
fi

cd "$ref_dir"
if [ -f package-lock.json ]; then
  npm ci --no-audit --no-fund
else
  npm install --no-audit --no-fund
fi
node -e "require('mikktspace')" || {
  echo "setup-npm.sh: the mikktspace package did not load from $ref_dir/node_modules" >&2
  exit 1
}
echo "setup-npm.sh: reference tangents ready in $ref_dir"

validator_dir="$here/tests/gltf_validator"
cd "$validator_dir"
npm ci --no-audit --no-fund
node -e "require('gltf-validator')" || {
  echo "setup-npm.sh: the gltf-validator package did not load from $validator_dir/node_modules" >&2
  exit 1
}
echo "setup-npm.sh: glTF validator ready in $validator_dir"
