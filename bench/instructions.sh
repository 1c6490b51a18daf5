#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Instructions executed per reconstruction stage (valgrind's callgrind): a figure that does not
# move with the machine's load, for comparing two builds of the geometry core. Wall-clock times
# on a shared 2-core VM vary by +-25 % between runs and phases; instruction counts repeat to the
# last digit, so a change of 1 % is visible. They are not a time: cache misses cost no
# instructions (bench_recon gives the times).
#
# Usage: bench/instructions.sh [-b BUILD_DIR] [INPUT...]
#   BUILD_DIR  a Release build (default: build); its cli/scanmesh is run
#   INPUT      points or meshes as for `scanmesh reconstruct` (default: the bunny's points from
#              $SCANMESH_DATA)
# Needs valgrind (Debian: apt-get install valgrind). About 40x slower than a plain run.
set -euo pipefail
cd "$(dirname "$0")/.."

build=build
if [ "${1:-}" = "-b" ]; then
  build=${2:?"-b needs a build directory"}
  shift 2
fi
if [ "${1:-}" = "-h" ] || [ "${1:-}" = "--help" ]; then
  sed -n '3,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'
  exit 0
fi
tool="$build/cli/scanmesh"
if [ ! -x "$tool" ]; then
  echo "instructions: $tool not found: build first (cmake --build $build)" >&2
  exit 2
fi
for t in valgrind callgrind_annotate; do
  if ! command -v "$t" >/dev/null 2>&1; then
    echo "instructions: '$t' is missing: apt-get install valgrind" >&2
    exit 2
  fi
done
if [ $# -eq 0 ]; then
  if [ -z "${SCANMESH_DATA:-}" ]; then
    echo "instructions: no INPUT and SCANMESH_DATA is not set" >&2
    exit 2
  fi
  set -- "$SCANMESH_DATA/bunny/reconstruction/bun_zipper_vertices.xyz"
fi

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
valgrind --tool=callgrind --callgrind-out-file="$work/cg.out" \
  "$tool" reconstruct "$@" -o "$work/out.ply" --json >"$work/summary.json" 2>"$work/valgrind.log" || {
  echo "instructions: the run failed:" >&2
  tail -5 "$work/valgrind.log" >&2
  exit 1
}
reduced=$(grep -o '"reduced_points": *[0-9]*' "$work/summary.json" | grep -o '[0-9]*$')
callgrind_annotate --inclusive=yes --threshold=100 "$work/cg.out" 2>/dev/null >"$work/inclusive.txt"

# stage label, then the start of its function's name (the first, largest, line that matches
# is the function itself; its lambdas follow with smaller counts)
stages=(
  "reconstruct (all)|scanmesh::recon::reconstruct("
  "  spacing estimate|scanmesh::recon::estimate_spacing("
  "  cube reduction|scanmesh::recon::cube_reduce"
  "  projection|scanmesh::recon::project_to_local_planes("
  "  normals|scanmesh::recon::estimate_frames("
  "  front|scanmesh::recon::advance_front("
  "    turning points|Builder::mark_turning_points("
  "    bulk|scanmesh::recon::detail::bulk_triangles("
  "    growth|Builder::grow("
  "    fan repairs|Builder::repair_fans("
  "  refine|scanmesh::recon::insert_unused_points("
  "  gaps|scanmesh::recon::fill_holes("
)
echo "input: $*"
echo "build: $build (reduced points: $reduced)"
printf '%-22s %16s %12s\n' "stage" "instructions" "per red. pt"
for s in "${stages[@]}"; do
  label=${s%%|*}
  name=${s#*|}
  count=$({ grep -F "$name" "$work/inclusive.txt" || true; } | head -1 | awk '{gsub(",", "", $1); print $1}')
  [ -n "$count" ] || count=0
  awk -v l="$label" -v c="$count" -v r="$reduced" \
    'BEGIN { printf "%-22s %16.0f %12.0f\n", l, c, (r > 0 ? c / r : 0) }'
done
