#!/bin/bash
# The adaptive grid's time against Embree's at several grid densities, as
# quoted in docs/results.md ("Fewer, fuller cells for packed triangles"):
#
#   docs/density_sweep.sh RAYNODE OUT.csv ROUNDS "D1 D2 ..." SCENE...
#
# Each round runs, for each SCENE (an SPD name[:size] with its flags in one
# word, e.g. "mount:6 -t 6", or a scene file, made as docs/ab_accel.sh says)
# and each density D (grid cells per primitive, at every level), `bench
# accel SCENE --repeat 2 --width 256 --height 256 --grid-density D --json`.
# OUT.csv gets a row per run: round, scene, density and the bench's figures.
set -u
bin=$(realpath "${1:?RAYNODE}"); out=$(realpath -m "${2:?OUT.csv}"); rounds=${3:?ROUNDS}; densities=${4:?DENSITIES}
shift 4
raw=$(mktemp); trap 'rm -f "$raw"' EXIT
for round in $(seq 1 "$rounds"); do
  for spec in "$@"; do
    for d in $densities; do
      # $spec is split on purpose: "mount:6 -t 6" is a scene and its flags.
      # shellcheck disable=SC2086
      j=$("$bin" bench accel $spec --repeat 2 --width 256 --height 256 --grid-density "$d" --json 2>/dev/null |
          tr -d '\n ')
      echo "$round|$spec|$d|$j" >> "$raw"
    done
  done
done
python3 - "$raw" "$out" <<'PY'
import csv, json, sys
keys = ["grid_over_embree_time", "grid_rays_per_s", "embree_rays_per_s", "tests_per_ray", "cells_per_ray",
        "grid_over_embree_memory"]
with open(sys.argv[2], "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(["round", "scene", "density"] + keys)
    for line in open(sys.argv[1]):
        rnd, scene, density, j = line.rstrip("\n").split("|", 3)
        try:
            d = json.loads(j)[0]
        except (ValueError, IndexError):
            continue  # a run that failed leaves no row
        w.writerow([rnd, scene, density] + [d.get(k, 0) for k in keys])
PY
wc -l "$out"
