#!/bin/bash
# Instructions per ray of two raynode builds, counted by callgrind: a
# measure that a noisy machine does not blur, as quoted in docs/results.md
# ("Cells holding sub-grids").
#
#   docs/ab_instructions.sh OLD NEW OUT.csv SCENE...
#
# OLD and NEW are raynode binaries; SCENE is an SPD name[:size] or a scene
# file, made as docs/ab_accel.sh says. Each build renders each scene in
# sequential mode at 64x64 under `valgrind --tool=callgrind`, counting only
# the instructions inside the tracer's queries (intersect_closest and
# intersect_any: traversal and intersection tests, not shading). OUT.csv
# gets a row per run: build (old|new), scene, instructions, rays, cells
# visited and tests, and whether the new image equals the old one byte for
# byte. With COLLECT=build in the environment it counts the instructions
# inside build_grid instead (the grid's build, once per run). Needs
# valgrind (apt-get install valgrind).
set -u
collect=(--toggle-collect='*intersect_closest<*' --toggle-collect='*intersect_any<*')
[ "${COLLECT:-queries}" = build ] && collect=(--toggle-collect='raynode::core::build_grid*')
old=$(realpath "${1:?OLD}"); new=$(realpath "${2:?NEW}"); out=$(realpath -m "${3:?OUT.csv}")
shift 3
command -v valgrind > /dev/null || { echo "ab_instructions.sh: valgrind is not installed" >&2; exit 1; }
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
echo "binary,scene,instructions,rays,cells_visited,tests,image_equal" > "$out"
n=0
for spec in "$@"; do
  n=$((n + 1))
  for build in old new; do
    bin=$old; [ "$build" = new ] && bin=$new
    valgrind --tool=callgrind --callgrind-out-file="$tmp/$build.$n.out" "${collect[@]}" \
      "$bin" render "$spec" --mode sequential --width 64 --height 64 -o "$tmp/$build.$n.ppm" \
      --stats="$tmp/$build.$n.json" > "$tmp/$build.$n.log" 2>&1 || { echo "ab_instructions.sh: $build failed on $spec:" >&2; grep -v "^==" "$tmp/$build.$n.log" | tail -n 3 >&2; exit 1; }
    ir=$(grep -o 'Collected : [0-9]*' "$tmp/$build.$n.log" | awk '{print $3}')
    same=-
    [ "$build" = new ] && { cmp -s "$tmp/old.$n.ppm" "$tmp/new.$n.ppm" && same=yes || same=no; }
    python3 - "$tmp/$build.$n.json" "$build" "$spec" "$ir" "$same" >> "$out" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
print(",".join([sys.argv[2], sys.argv[3], sys.argv[4], str(s["rays"]["total"]), str(s["cells_visited"]),
                str(sum(s["tests"].values())), sys.argv[5]]))
PY
  done
done
