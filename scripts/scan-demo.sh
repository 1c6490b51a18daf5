#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The whole product in one command: installs what is missing, builds scanmeshd and scanctl
# (Release, ./build), starts scanmeshd in the foreground on a temporary socket with the simulated
# scanner (config/scanmesh-sim.toml: a Micro-Epsilon ILD1420 point sensor at 10 kHz on a GRBL
# stage, both protocol emulators on ptys read by the real drivers, scanning the built-in
# `container` part in serpentine from above, about 25 s of real motion) through the acquisition
# pipeline (MCAP journal, incremental mesher, SQLite catalog), runs a scan to completion with
# scanctl (progress shown), exports the mesh and a preview picture into ./out/, and stops the
# daemon.
#
# Usage: scripts/scan-demo.sh [--mesh FILE]
#   --mesh FILE  scan your own part (.stl .ply .obj) instead of the built-in one.
# The batch tool's own demo is scripts/demo.sh.
set -euo pipefail

usage() { sed -n '3,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//' >&2; }
mesh=""
if [ $# -eq 2 ] && [ "$1" = "--mesh" ]; then
  [ -f "$2" ] || { echo "scan-demo: '$2' is not a readable file" >&2; exit 2; }
  mesh=$(realpath "$2")
elif [ $# -ne 0 ]; then
  usage
  [ "${1:-}" = "-h" ] || [ "${1:-}" = "--help" ] && exit 0 || exit 2
fi
cd "$(dirname "$0")/.."

bash scripts/setup.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j2 --target scanmeshd scanctl

out="$PWD/out"
mkdir -p "$out"
tmp=$(mktemp -d)
# The example configuration, with this demo's folders: exports may go to ./out.
sed "s|^\[daemon\]|[daemon]\nexport_dirs = [\"$out\"]|" config/scanmesh-sim.toml > "$tmp/scanmesh.toml"
build/daemon/scanmeshd --config "$tmp/scanmesh.toml" --socket "$tmp/control.sock" \
  --state-dir "$tmp/state" --foreground 2> "$tmp/scanmeshd.log" &
daemon=$!
cleanup() {
  kill -TERM "$daemon" 2>/dev/null && wait "$daemon" 2>/dev/null || true
}
trap cleanup EXIT
ctl() { build/daemon/scanctl --socket "$tmp/control.sock" "$@"; }
for _ in $(seq 100); do ctl version >/dev/null 2>&1 && break; sleep 0.1; done
ctl version

# The configuration's pass over the top, through the emulators and the real drivers. (The
# in-process simulation, `--param transport=in-process`, can also take a line profiler and four
# views: `--param sensor=line --param path=views --param speed_mm_s=40`.)
params=()
[ -n "$mesh" ] && params+=(--param "mesh=$mesh")
ctl scan start --name demo "${params[@]}" --wait
ctl mesh export --path "$out/scan.stl"
ctl mesh preview --path "$out/scan_preview.png"
ctl scan list
kill -TERM "$daemon"
wait "$daemon" || { echo "scan-demo: scanmeshd did not stop cleanly; its log: $tmp/scanmeshd.log" >&2; exit 1; }
trap - EXIT
echo
echo "mesh:    $out/scan.stl"
echo "preview: $out/scan_preview.png"
echo "journal: $(ls "$tmp"/state/scans/*.mcap | head -1) (scanmesh replay FILE re-meshes it)"
echo "catalog: $tmp/state/catalog.sqlite (daemon log: $tmp/scanmeshd.log)"
