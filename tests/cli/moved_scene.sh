#!/usr/bin/env bash
# The rendering commands trace in a space whose origin is the eye
# (core::eye_at_origin): a scene moved far from the origin, whose
# coordinates stay exact floats there, renders the same bytes as where it
# was, in every mode. (Traced where it lies, lattice:4 moved by 1e3
# differed on 2% of its pixels: ray origins a thousand units out carry
# 1/16 000 of a unit of rounding, and its glass spheres refract chaotically.)
#
#   moved_scene.sh RAYNODE WORKDIR
set -uo pipefail
raynode=$(realpath "$1") workdir=$2
rm -rf "$workdir" && mkdir -p "$workdir" && cd "$workdir" || exit 2

fail=0
for mode in sequential svm dataflow; do
  nodes=()
  [ "$mode" = sequential ] || nodes=(--nodes 3)
  for move in 0,0,0 1024,-2048,512; do
    if ! timeout --kill-after=5 100 "$raynode" render lattice:4 --width 48 --height 48 --quiet --timeout 60 \
        --mode "$mode" "${nodes[@]}" --translate "$move" -o "$mode-$move.ppm" 2> "$mode-$move.err"; then
      echo "FAIL: $mode --translate $move:"; cat "$mode-$move.err"; fail=1
    fi
  done
  if cmp -s "$mode-0,0,0.ppm" "$mode-1024,-2048,512.ppm"; then
    echo "ok: $mode: moved by (1024, -2048, 512), the same image"
  else
    echo "FAIL: $mode: lattice:4 moved by (1024, -2048, 512) renders another image"; fail=1
  fi
done
exit $fail
