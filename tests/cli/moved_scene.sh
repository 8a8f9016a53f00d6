#!/usr/bin/env bash
# The rendering commands trace in a space whose origin is the eye
# (core::eye_at_origin):
#  - a scene file moved far from the origin, whose coordinates stay exact
#    floats there, renders the same bytes as where it was, in every mode.
#    (Traced where it lies, lattice:4 moved by 1e3 differed on 2% of its
#    pixels: ray origins a thousand units out carry 1/16 000 of a unit of
#    rounding, and its glass spheres refract chaotically.)
#  - --translate is composed with that move and rounded once
#    (core::eye_at_origin_after), so it cancels exactly: lattice:3, whose
#    thirds a float cannot hold at 1e4, renders the same bytes moved by 1e4
#    (rounded there first, 10.7% of its pixels differed).
#
#   moved_scene.sh RAYNODE WORKDIR
set -uo pipefail
raynode=$(realpath "$1") workdir=$2
# shellcheck source=tests/cli/render_lib.sh
. "$(dirname "$0")/render_lib.sh"
same() {  # same A B WHAT
  if cmp -s "$1" "$2"; then echo "ok: $3, the same image"; else echo "FAIL: $3 renders another image"; fail=1; fi
}

"$raynode" scene write lattice:4 --translate 1024,-2048,512 -o moved.nff || { echo "FAIL: scene write"; exit 1; }
for mode in sequential svm dataflow; do
  nodes=()
  [ "$mode" = sequential ] || nodes=(--nodes 3)
  render "$mode-here.ppm" lattice:4 --mode "$mode" "${nodes[@]}"
  render "$mode-moved.ppm" moved.nff --mode "$mode" "${nodes[@]}"
  same "$mode-here.ppm" "$mode-moved.ppm" "$mode: lattice:4 written moved by (1024, -2048, 512)"
done
render thirds-here.ppm lattice:3
render thirds-moved.ppm lattice:3 --translate 1e4,-1e4,1e4
same thirds-here.ppm thirds-moved.ppm "sequential: lattice:3 --translate 1e4,-1e4,1e4"
exit $fail
