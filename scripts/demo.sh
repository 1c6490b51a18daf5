#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Demo: installs what is missing, builds the `scanmesh` tool (Release, ./build) and reconstructs
# the built-in `container` reference part from a synthetic scan (with a shaded preview picture),
# then inspects the mesh and measures its deviation from the exact part. Everything it writes
# goes to ./out/.
#
# Usage: scripts/demo.sh [FILE]
#   FILE  your own input instead of the built-in part:
#         points (.xyz .txt .csv .asc) are reconstructed and inspected;
#         a mesh (.stl .ply .obj) is reconstructed from its vertices, or, when they are too sparse
#         or uneven to be a scan (typical of CAD exports), from a sample of its surface; the
#         result is then compared with the mesh.
# Environment: DEMO_NOISE (mm, default 0.02) is the scanner noise of the synthetic scan;
#              DEMO_POINTS (default 100000) is how many points to sample from a sparse mesh.
set -euo pipefail

usage() { sed -n '3,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//' >&2; }

input=""
if [ $# -gt 1 ] || { [ $# -eq 1 ] && { [ "$1" = "-h" ] || [ "$1" = "--help" ]; }; }; then
  usage
  [ $# -eq 1 ] && exit 0 || exit 2
fi
if [ $# -eq 1 ]; then
  if [ ! -f "$1" ]; then
    echo "demo: '$1' is not a readable file" >&2
    exit 2
  fi
  input=$(realpath "$1")  # before the cd below
fi
noise=${DEMO_NOISE:-0.02}
sample_points=${DEMO_POINTS:-100000}

cd "$(dirname "$0")/.."
root=$(pwd)

step() { printf '\n==> %s\n' "$*"; }

step "setup (Debian packages)"
bash scripts/setup.sh

step "build (Release, ./build, target scanmesh)"
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build --target scanmesh
scanmesh="$root/build/cli/scanmesh"
mkdir -p out

# Reads one number or true/false from a one-line JSON object printed by scanmesh (flat keys only).
json_field() { sed -n "s/.*\"$2\":\([-0-9.eE+]*\|true\|false\)[,}].*/\1/p" <<<"$1"; }

files=()  # what to list at the end
ref=""    # reference surface for the deviation, if any
if [ -z "$input" ]; then
  name=container
  points="out/${name}_points.xyz"
  ref="out/${name}_ref.stl"
  step "generate: synthetic scan of the built-in '$name' part (noise ${noise} mm)"
  "$scanmesh" generate --part "$name" --noise "$noise" -o "$points" --mesh "$ref"
  files+=("$points" "$ref")
else
  base=$(basename "$input")
  name=${base%.*}
  ext=$(tr '[:upper:]' '[:lower:]' <<<"${base##*.}")
  case "$ext" in
    xyz | txt | csv | asc)
      points="$input"
      ;;
    stl | ply | obj)
      step "inspect the input mesh: $input"
      report=$("$scanmesh" inspect --json "$input")
      triangles=$(json_field "$report" triangles)
      if [ "${triangles:-0}" -eq 0 ]; then
        echo "no triangles: using its vertices as points (no deviation without a surface)"
        points="$input"
      else
        ref="$input"
        # What the reconstruction is compared with: its loops, components and genus are the
        # truth for the output only when the input mesh is itself a clean manifold surface.
        loops=$(json_field "$report" boundary_loops)
        comps=$(json_field "$report" components)
        nm_edges=$(json_field "$report" non_manifold_edges)
        nm_verts=$(json_field "$report" non_manifold_vertices)
        dups=$(json_field "$report" duplicate_triangles)
        crossing=$(json_field "$report" self_intersections)
        genus_txt="genus $(json_field "$report" genus)"
        [ "$(json_field "$report" genus_defined)" = true ] || genus_txt="genus undefined"
        echo "input mesh: $(json_field "$report" vertices) vertices, $(json_field "$report" triangles)" \
          "triangles, $loops boundary loops, $comps component(s), $genus_txt"
        if [ "${nm_edges:-0}" -gt 0 ] || [ "${nm_verts:-0}" -gt 0 ] || [ "${dups:-0}" -gt 0 ] ||
          [ "${crossing:-0}" -gt 0 ]; then
          echo "note: the input mesh is not a clean surface ($nm_edges non-manifold edges," \
            "$nm_verts non-manifold vertices, $dups duplicate triangles, $crossing crossing" \
            "triangle pairs); points sampled on its folds and flaps can leave extra small" \
            "boundary loops there (see 'scanmesh inspect $input')"
        fi
        # A scan-like mesh has many evenly spaced vertices and well-shaped triangles; a CAD
        # export has few vertices, long edges across flat faces and slivers. Its vertices alone
        # would leave the flat faces without points, so its surface is sampled instead
        # (`scanmesh inspect` decides: scan_like_vertices).
        if [ "$(json_field "$report" scan_like_vertices)" != true ]; then
          points="out/${name}_points.xyz"
          thin=$(json_field "$report" frac_min_angle_below_20)
          echo "vertices too few or uneven to be a scan (mean edge" \
            "$(json_field "$report" mean_edge_length), max edge" \
            "$(json_field "$report" max_edge_length)," \
            "$(awk -v t="$thin" 'BEGIN { printf "%.0f", 100 * t }')% thin triangles):" \
            "sampling about $sample_points points from its surface"
          "$scanmesh" generate --mesh-in "$input" --points "$sample_points" -o "$points"
          files+=("$points")
        else
          echo "$(json_field "$report" vertices) well-spread vertices: using them as the points"
          points="$input"
        fi
      fi
      ;;
    *)
      echo "demo: unsupported input '$base' (use .xyz .txt .csv .asc .stl .ply .obj)" >&2
      exit 2
      ;;
  esac
fi

mesh="out/${name}.stl"
preview="out/${name}_preview.png"
step "reconstruct: $points -> $mesh (picture: $preview)"
"$scanmesh" reconstruct "$points" -o "$mesh" --preview "$preview"
files+=("$mesh" "$preview")

step "inspect: $mesh"
"$scanmesh" inspect "$mesh"

if [ -n "$ref" ]; then
  png="out/${name}_deviation.png"
  step "deviation: $mesh against $ref"
  "$scanmesh" deviation "$mesh" --ref "$ref" --png "$png"
  files+=("$png")
fi

step "done; files written under $root/out:"
for f in "${files[@]}"; do
  printf '  %-36s %10s bytes\n' "$f" "$(stat -c %s "$f")"
done
echo "View the meshes with any STL viewer (e.g. meshlab, f3d) and the picture with an image viewer."
echo "For CAD, a scanner's noise can be taken out and the bevelled sharp edges put back (both on"
echo "request; see README.md): build/cli/scanmesh reconstruct $points -o out/${name}_cad.stl --denoise --sharpen"
