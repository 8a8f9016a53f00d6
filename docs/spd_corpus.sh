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
here=$(dirname "$(realpath "$0")")  # corpus_csv.py beside this script
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
python3 "$here/corpus_csv.py" "$raw" "$out"
