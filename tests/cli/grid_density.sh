#!/usr/bin/env bash
# --grid-density reaches the grid of every scene: the top grid of the
# adaptive grid as well as the uniform grid, in bench accel and validate.
# Cells ~ density x primitives (core/grid.h), so 8x the density must give
# 4x-16x the top grid's cells (the per-axis rounding moves the product).
#
#   grid_density.sh RAYNODE WORKDIR
set -uo pipefail
raynode=$(realpath "$1") workdir=$2
rm -rf "$workdir" && mkdir -p "$workdir" && cd "$workdir" || exit 2

fail=0
top_cells() {  # JSON FILE (a bench accel array or a validate object): the top grid's cells
  python3 -c 'import json, sys
j = json.load(open(sys.argv[1]))
g = (j[0] if isinstance(j, list) else j)["grid"]
print(g["levels"][0]["cells"])' "$1"
}
for grid in adaptive uniform; do
  for cmd in "bench accel" "validate"; do
    name=${cmd// /_}-$grid
    for density in 2 16; do
      # shellcheck disable=SC2086
      if ! timeout --kill-after=5 100 "$raynode" $cmd teapot:3 --width 16 --height 16 --grid "$grid" \
          --grid-density "$density" --json "$name-$density.json" > /dev/null 2> "$name-$density.err"; then
        echo "FAIL: $cmd --grid $grid --grid-density $density:"; cat "$name-$density.err"; fail=1
      fi
    done
    [ -s "$name-2.json" ] && [ -s "$name-16.json" ] || continue
    c2=$(top_cells "$name-2.json") c16=$(top_cells "$name-16.json")
    echo "$cmd --grid $grid: top grid cells $c2 at density 2, $c16 at density 16"
    if [ -z "$c2" ] || [ -z "$c16" ] || [ $((c16)) -lt $((4 * c2)) ] || [ $((c16)) -gt $((16 * c2)) ]; then
      echo "FAIL: $cmd --grid $grid: 8x the density should give 4x-16x the top grid's cells"; fail=1
    fi
  done
done
exit $fail
