#!/bin/bash
# The grid's memory against Embree's over the benchmark corpus, as quoted in
# docs/results.md ("Memory against Embree"):
#
#   docs/accel_memory.sh RAYNODE OUT.csv SCENE...
#
# Run where the scene files are (made as docs/ab_accel.sh says). Each SCENE
# is an SPD name[:size] with its flags in one word ("balls:4 -t 1") or a
# scene file; one `bench accel SCENE --repeat 1 --width 16 --height 16
# --json` each (the bytes do not depend on the rays). OUT.csv gets a row
# per scene: its primitives and the grid's references, the grid's bytes
# with its packed cells and the packed cells' share of them, the bytes
# Embree's build kept, and the ratio.
set -u
bin=$(realpath "${1:?RAYNODE}"); out=$(realpath -m "${2:?OUT.csv}")
shift 2
raw=$(mktemp); trap 'rm -f "$raw"' EXIT
for spec in "$@"; do
  # $spec is split on purpose: "balls:4 -t 1" is a scene and its flags.
  # shellcheck disable=SC2086
  j=$("$bin" bench accel $spec --repeat 1 --width 16 --height 16 --json 2>/dev/null | tr -d '\n ')
  echo "$spec|$j" >> "$raw"
done
python3 - "$raw" "$out" <<'PY'
import csv, json, sys
with open(sys.argv[2], "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(["scene", "primitives", "grid_references", "grid_bytes", "packed_bytes", "embree_bytes",
                "grid_over_embree_memory"])
    for line in open(sys.argv[1]):
        scene, j = line.rstrip("\n").split("|", 1)
        try:
            d = json.loads(j)[0]
        except (ValueError, IndexError):
            continue  # a run that failed leaves no row
        w.writerow([scene, d["primitives"], d["grid_references"], d["grid_bytes"], d["packed_bytes"], d["embree_bytes"],
                    f"{d['grid_over_embree_memory']:.3f}"])
PY
wc -l "$out"
