#!/bin/bash
# A/B of two raynode builds on a small machine, one benchmark at a time, as
# quoted in docs/results.md ("Packed sphere cells"):
#
#   docs/ab_pair.sh OLD NEW OUT.csv ROUNDS SCENE...
#
# OLD and NEW are raynode binaries. Each round runs, for each SCENE (an SPD
# name[:size] with its flags in one word, e.g. "balls:4 -t 1", or a scene
# file, made as docs/ab_accel.sh says), `bench accel SCENE --repeat 3
# --width 256 --height 256 --json` with OLD, then with NEW, so that a burst
# of load falls on both. OUT.csv gets a row per run: build (old|new), round,
# scene and the bench's figures.
set -u
old=$(realpath "${1:?OLD}"); new=$(realpath "${2:?NEW}"); out=$(realpath -m "${3:?OUT.csv}"); rounds=${4:?ROUNDS}
shift 4
raw=$(mktemp); trap 'rm -f "$raw"' EXIT
for round in $(seq 1 "$rounds"); do
  for spec in "$@"; do
    for build in old new; do
      bin=$old; [ "$build" = new ] && bin=$new
      # $spec is split on purpose: "balls:4 -t 1" is a scene and its flags.
      # shellcheck disable=SC2086
      j=$("$bin" bench accel $spec --repeat 3 --width 256 --height 256 --json 2>/dev/null | tr -d '\n ')
      echo "$build|$round|$spec|$j" >> "$raw"
    done
  done
done
python3 - "$raw" "$out" <<'PY'
import csv, json, sys
keys = ["grid_rays_per_s", "embree_rays_per_s", "grid_over_embree_time", "grid_build_s", "embree_build_s",
        "tests_per_ray", "cells_per_ray", "packed_sphere_blocks", "grid_over_embree_memory"]
with open(sys.argv[2], "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(["binary", "round", "scene"] + keys)
    for line in open(sys.argv[1]):
        build, rnd, scene, j = line.rstrip("\n").split("|", 3)
        try:
            d = json.loads(j)[0]
        except (ValueError, IndexError):
            continue  # a run that failed or timed out leaves no row
        w.writerow([build, rnd, scene] + [d.get(k, 0) for k in keys])
PY
wc -l "$out"
