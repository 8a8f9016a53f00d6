#!/bin/bash
# The grid against Embree on every scene the SPD generators make: each
# generator at its default size, at a larger size, and tessellated where it
# has spheres or cones (-t 1), each alone and as stadium variants on a
# square floor 100x and 1000x its width, as quoted in docs/results.md ("Every
# SPD scene, alone and on stadium floors"):
#
#   docs/spd_corpus.sh RAYNODE OUT.csv ROUNDS [SCENE...]
#
# SCENE is an SPD name[:size] with its flags in one word, e.g. "balls -t 1"
# (default: the list below). For each scene and floor (none, --floor 100,
# --floor 1000), ROUNDS alternated rounds of `bench accel SCENE [--floor K]
# --repeat 3 --width 256 --height 256 --json`, one benchmark at a time, then
# one `validate SCENE [--floor K] --json` (its defaults: 512x512 primary
# rays, 400,000 random rays and their secondaries). OUT.csv gets a row per
# scene, floor and round in docs/scanned_meshes.sh's columns (the scene in
# the `mesh` column), its svm columns empty.
set -u
bin=$(realpath "${1:?RAYNODE}"); out=$(realpath -m "${2:?OUT.csv}"); rounds=${3:?ROUNDS}
shift 3
scenes=("$@")
if [ ${#scenes[@]} -eq 0 ]; then
  scenes=(balls gears jacks lattice mount rings sombrero teapot tetra tree shells
          "balls:5" "gears:5" "jacks:5" "lattice:8" "mount:7" "rings:8" "sombrero:4" "teapot:16" "tetra:8"
          "tree:12" "shells:6"
          "balls -t 1" "jacks -t 1" "lattice -t 1" "rings -t 1" "tree -t 1")
fi
raw=$(mktemp); trap 'rm -f "$raw"' EXIT
floors=("" "--floor 100" "--floor 1000")
for round in $(seq 1 "$rounds"); do
  for s in "${scenes[@]}"; do
    for f in "${floors[@]}"; do
      # $s and $f are split on purpose: a scene and its flags, a flag and its value.
      # shellcheck disable=SC2086
      j=$("$bin" bench accel $s $f --repeat 3 --width 256 --height 256 --json 2>/dev/null | tr -d '\n ')
      echo "bench|$round|$s|${f#--floor }|$j" >> "$raw"
    done
  done
done
for s in "${scenes[@]}"; do
  for f in "${floors[@]}"; do
    # shellcheck disable=SC2086
    j=$("$bin" validate $s $f --json 2>/dev/null | tr -d '\n ')
    echo "validate|0|$s|${f#--floor }|$j" >> "$raw"
  done
done
python3 - "$raw" "$out" <<'PY'
import csv, json, sys
bench, extra = [], {}
for line in open(sys.argv[1]):
    kind, rnd, scene, floor, j = line.rstrip("\n").split("|", 4)
    floor = floor or "0"
    try:
        d = json.loads(j)
    except ValueError:
        continue  # a run that failed leaves no figure
    if kind == "bench":
        bench.append((rnd, scene, floor, d[0]))
    else:
        extra[(scene, floor)] = {"mismatches": d["mismatches"], "validate_rays": d["rays"]}
keys = ["mismatches", "validate_rays", "svm_adaptive_pages_per_pixel", "svm_uniform_pages_per_pixel",
        "adaptive_efficiency_64", "uniform_efficiency_64"]
with open(sys.argv[2], "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(["mesh", "floor", "round", "primitives", "grid_over_embree_time", "grid_rays_per_s",
                "embree_rays_per_s", "tests_per_ray", "cells_per_ray", "grid_build_s", "embree_build_s",
                "grid_bytes", "embree_bytes"] + keys)
    for rnd, scene, floor, d in bench:
        e = extra.get((scene, floor), {})
        w.writerow([scene, floor, rnd, d["primitives"], f"{d['grid_over_embree_time']:.4f}",
                    f"{d['grid_rays_per_s']:.0f}", f"{d['embree_rays_per_s']:.0f}", f"{d['tests_per_ray']:.2f}",
                    f"{d['cells_per_ray']:.2f}", f"{d['grid_build_s']:.6f}", f"{d['embree_build_s']:.6f}",
                    d["grid_bytes"], d["embree_bytes"]] + [e.get(k, "") for k in keys])
PY
