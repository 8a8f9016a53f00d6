#!/bin/sh
# Reproduces the render-timing table of docs/gallery.md: 512x512, 1 sample
# per pixel, each paper scene in --mode sequential and --mode shared, best
# wall time of REPEAT runs (default 3). rays/s = all rays cast (primary +
# shadow + reflected + refracted) / wall seconds of the render (scene
# generation and grid build excluded). "cpu s" is the process CPU time of the
# best sequential run: on a loaded machine it is the steadier number.
# Usage: docs/render_timings.sh [path/to/raynode] [REPEAT]
set -eu
RAYNODE=${1:-build/apps/raynode}
REPEAT=${2:-3}
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
echo "| scene | primitives | rays | sequential s | (cpu s) | sequential Mrays/s | shared s | shared Mrays/s | speedup |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|"
for spec in "teapot:8" "mount:6 -t 6" "rings:4 -t 1" "rings:3 -t 1" "tetra:9"; do
  for mode in sequential shared; do
    best=""
    for i in $(seq "$REPEAT"); do
      # shellcheck disable=SC2086
      "$RAYNODE" render $spec --width 512 --height 512 --mode "$mode" -o "$TMP/out.png" --stats "$TMP/s.json" -q
      w=$(jq '.time.wall_s' "$TMP/s.json")
      if [ -z "$best" ] || [ "$(echo "$w < $best" | bc -l)" = 1 ]; then
        best=$w
        cpu=$(jq '.time.cpu_s' "$TMP/s.json")
      fi
    done
    rays=$(jq '.rays.total' "$TMP/s.json")
    prims=$(jq '.database.primitives' "$TMP/s.json")
    eval "t_$mode=$best"
    if [ "$mode" = sequential ]; then cpu_sequential=$cpu; fi
  done
  # shellcheck disable=SC2154
  printf '| `%s` | %s | %s | %.3f | %.3f | %.2f | %.3f | %.2f | %.2f |\n' "$spec" "$prims" "$rays" \
    "$t_sequential" "$cpu_sequential" "$(echo "$rays / $t_sequential / 1000000" | bc -l)" \
    "$t_shared" "$(echo "$rays / $t_shared / 1000000" | bc -l)" "$(echo "$t_sequential / $t_shared" | bc -l)"
done
