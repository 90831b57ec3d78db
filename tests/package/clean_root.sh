#!/usr/bin/env bash
# The package on a clean system (ctest Package.CleanRootHeavy): builds the
# .deb (cpack in BUILD), makes a fresh Debian 12 root (debootstrap, minbase),
# installs the package there with apt-get (its dependencies from Debian),
# then, inside the root, bakes a generated pair with the installed binary
# into PNG, EXR and TIFF (TIFF and reading need the image module, found in
# /usr/lib/nmbake), runs --version, shows `man nmbake` and imports the
# Python package. Exit 77 (skipped) without root, debootstrap or a Debian
# mirror; any other failure fails the test.
#   tests/package/clean_root.sh BUILD_DIR
set -euo pipefail
build=$(cd "$1" && pwd)
here=$(cd "$(dirname "$0")/../.." && pwd)
mirror=${NMBAKE_DEBIAN_MIRROR:-http://deb.debian.org/debian}

skip() { echo "skipped: $*"; exit 77; }
[ "$(id -u)" = 0 ] || skip "needs root (debootstrap, chroot)"
command -v debootstrap >/dev/null || skip "debootstrap is not installed (tools/setup installs it)"
command -v cpack >/dev/null || skip "cpack is not installed"

root=$(mktemp -d /var/tmp/nmbake-clean-root.XXXXXX)
cleanup() {
  umount "$root/proc" 2>/dev/null || true
  rm -rf "$root"
}
trap cleanup EXIT

echo "== the package"
(cd "$build" && cpack -G DEB >/dev/null)
deb=$(ls -t "$build"/nmbake_*.deb | head -n 1)
echo "$(basename "$deb"): $(du -h "$deb" | cut -f1)"
dpkg-deb --field "$deb" Depends

echo "== a fresh Debian 12 root (debootstrap --variant=minbase bookworm)"
start=$(date +%s)
if ! debootstrap --variant=minbase bookworm "$root" "$mirror" >"$root.log" 2>&1; then
  if grep -qiE "resolv|connect|download|Failed getting release" "$root.log"; then
    tail -3 "$root.log"; rm -f "$root.log"; skip "no Debian mirror reachable at $mirror"
  fi
  tail -20 "$root.log"; rm -f "$root.log"; exit 1
fi
rm -f "$root.log"
echo "debootstrap: $(($(date +%s) - start)) s"
cat >"$root/etc/apt/sources.list" <<SOURCES
deb $mirror bookworm main
deb $mirror bookworm-updates main
deb http://deb.debian.org/debian-security bookworm-security main
SOURCES
cp /etc/resolv.conf "$root/etc/resolv.conf"
mount -t proc proc "$root/proc"

echo "== apt-get install ./$(basename "$deb") (and man-db, to read the manual)"
cp "$deb" "$root/tmp/"
start=$(date +%s)
chroot "$root" /usr/bin/env DEBIAN_FRONTEND=noninteractive sh -c \
  "apt-get update -q >/dev/null && apt-get install -y -q /tmp/$(basename "$deb") man-db >/tmp/install.log 2>&1" ||
  { tail -30 "$root/tmp/install.log"; exit 1; }
echo "install: $(($(date +%s) - start)) s"

echo "== inside the root"
mkdir -p "$root/tmp/pair"
"$build/nmbake-gen" sphere --out-dir "$root/tmp/pair" --high-cells 64 --low-cells 4 >/dev/null
chroot "$root" /bin/sh -ec '
  test ! -e /usr/local/bin/nmbake
  command -v nmbake
  nmbake --version
  cd /tmp/pair
  mkdir -p out
  nmbake bake --low sphere_low.obj --high sphere_high.ply --size 256 -o out/n.png -o out/n.exr -o out/n.tif
  for f in out/n.png out/n.exr out/n.tif; do test -s "$f" || { echo "missing $f"; exit 1; }; done
  nmbake diff out/n.png out/n.tif --max-mean 0.01
  ls -l out
  MANWIDTH=80 man --warnings nmbake 2>&1 >/tmp/man.txt | tee /tmp/man-warnings.txt
  test ! -s /tmp/man-warnings.txt
  head -n 12 /tmp/man.txt
  man -w nmbake-bake
  test -f /usr/share/bash-completion/completions/nmbake
  test -s /usr/share/nmbake/blender/nmbake_blender.zip
  if command -v python3 >/dev/null; then python3 -c "import nmbake; print(\"python: nmbake\", nmbake.__version__)"; fi
'
echo "clean root: the package installed, baked PNG, EXR and TIFF, and showed its manual"
