#!/usr/bin/env bash
# svm's pages per pixel with the primitive records in file order and in
# cell order (--primitive-order), beside the paper's uniform grid, as
# quoted in docs/results.md ("Primitive records in cell order"):
#
#   docs/primitive_order.sh RAYNODE OUT.csv NODES SIZE SCENE...
#
# For each SCENE four renders, svm on NODES nodes at SIZE x SIZE, all the
# node memory a cache: --grid uniform (file order, the paper's layout),
# then the adaptive grid with --primitive-order file, cell and auto (the
# row says which order auto took). Pages per pixel and the faults by
# segment are counts of what the tracer reads, the same on every run.
set -euo pipefail
raynode=${1:?RAYNODE}; out=${2:?OUT.csv}; nodes=${3:?NODES}; size=${4:?SIZE}
shift 4
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
echo "scene,grid,asked,primitive_order,pages_per_pixel,misses,primitive_misses,list_misses,directory_misses,shared_memory_bytes" > "$out.tmp"
for scene in "$@"; do
  for config in "uniform file" "adaptive file" "adaptive cell" "adaptive auto"; do
    read -r grid order <<< "$config"
    # shellcheck disable=SC2086  # a SCENE may carry its own options ("mount:6 -t 6")
    "$raynode" render $scene --mode svm --nodes "$nodes" --width "$size" --height "$size" --grid "$grid" \
      --primitive-order "$order" --quiet -o "$tmp/out.ppm" --stats "$tmp/stats.json"
    python3 - "$tmp/stats.json" "$scene" "$grid" "$order" >> "$out.tmp" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))["svm"]
m = s["misses_by_segment"]
print(f'"{sys.argv[2]}",{sys.argv[3]},{sys.argv[4]},{s["primitive_order"]},{s["pages_per_pixel"]:.3f},{s["misses"]},'
      f'{m["primitives"]},{m["lists"]},{m["directory"]},{s["shared_memory_bytes"]}')
PY
  done
done
mv "$out.tmp" "$out"
