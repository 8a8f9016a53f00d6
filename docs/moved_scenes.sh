#!/bin/bash
# Scaled and moved scenes against the untransformed render, as quoted in
# docs/results.md ("Scaled and moved scenes"):
#
#   docs/moved_scenes.sh RAYNODE OUT.csv SCENE...
#
# Each SCENE (SPD name[:size] or a scene file) is rendered at 128x128 in
# sequential, svm and dataflow (4 nodes) mode, as it is, scaled by 10^k
# (k = -6, -4, -2, 2, 4, 6; --scale), and moved by 10^k on all three axes
# (k = 2, 3, 4) twice: with --translate (translate:1e3), and as a file
# written there by `scene write --translate` (move:1e3), whose coordinates
# hold the floats' rounding at that place. OUT.csv gets a row per
# transformed render: scene, mode, transform, and the fraction of pixels
# where some channel differs from the untransformed render of the same mode
# by more than 8/255 (the issue's measure; 8-bit PPM values).
set -u
raynode=$(realpath "${1:?RAYNODE}"); out=$(realpath -m "${2:?OUT.csv}")
shift 2
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
echo "scene,mode,transform,differing_fraction" > "$out"
n=0
for spec in "$@"; do
  n=$((n + 1))
  for v in 1e2 1e3 1e4; do
    "$raynode" scene write "$spec" --translate "$v,$v,$v" -o "$tmp/$n.$v.nff" 2> "$tmp/err" ||
      echo "moved_scenes.sh: scene write $spec --translate $v: $(tail -n 1 "$tmp/err")" >&2
  done
  for mode in sequential svm dataflow; do
    nodes=()
    [ "$mode" = sequential ] || nodes=(--nodes 4)
    render() {  # SCENE OUT [transform options...]
      local scene=$1 file=$2; shift 2
      "$raynode" render "$scene" --mode "$mode" "${nodes[@]}" --width 128 --height 128 --quiet -o "$file" "$@" \
        2> "$tmp/err" || { echo "moved_scenes.sh: $scene $mode $*: $(tail -n 1 "$tmp/err")" >&2; return 1; }
    }
    render "$spec" "$tmp/$n.base.ppm" || continue
    for t in scale:1e-6 scale:1e-4 scale:1e-2 scale:1e2 scale:1e4 scale:1e6 translate:1e2 translate:1e3 \
        translate:1e4 move:1e2 move:1e3 move:1e4; do
      v=${t#*:}
      case "${t%%:*}" in
        scale) render "$spec" "$tmp/$n.t.ppm" --scale "$v" || continue ;;
        translate) render "$spec" "$tmp/$n.t.ppm" --translate "$v,$v,$v" || continue ;;
        *) [ -f "$tmp/$n.$v.nff" ] && render "$tmp/$n.$v.nff" "$tmp/$n.t.ppm" || continue ;;
      esac
      python3 - "$tmp/$n.base.ppm" "$tmp/$n.t.ppm" "$spec" "$mode" "$t" >> "$out" <<'PY'
import re, sys
def read(path):
    b = open(path, "rb").read()
    m = re.match(rb"P6\s+(\d+)\s+(\d+)\s+(\d+)\s", b)
    return int(m.group(1)) * int(m.group(2)), b[m.end():]
n, a = read(sys.argv[1])
_, b = read(sys.argv[2])
bad = sum(1 for i in range(n) if any(abs(a[3 * i + c] - b[3 * i + c]) > 8 for c in range(3)))
print(f"{sys.argv[3]},{sys.argv[4]},{sys.argv[5]},{bad / n:.6f}")
PY
    done
  done
done
wc -l "$out"
