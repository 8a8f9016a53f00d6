#!/usr/bin/env bash
# Re-runs the paper's experiments on the emulated iPSC/2 and regenerates
# docs/results.md from what they write: Table 2 (database characteristics)
# and Table 3 (svm synthesis times and efficiency, 512x512) from one
# `bench nodes` per database, Figures 8, 9 and 10 (efficiency, miss ratio
# and page traffic against cache size, 32 nodes) from two `sweep cache`.
#
#   docs/paper.sh [RAYNODE] [OUT]
#
# RAYNODE defaults to build/apps/raynode, OUT to docs/results/paper. Every
# run uses --machine ipsc2 (4 MiB nodes, 1 KiB pages, hypercube, model
# clock, the iPSC/2's documented costs), --shadow-rays all (the paper's
# ray count) and --grid uniform (the paper's one-level grid, its svm pages
# holding the primitives in the database's order). SIZE (default 512, the paper's) is Table 3's image side,
# SWEEP_SIZE (default 512) the cache sweeps'. About 10 minutes on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
raynode=${1:-build/apps/raynode}
out=${2:-docs/results/paper}
size=${SIZE:-512}
sweep_size=${SWEEP_SIZE:-512}
mkdir -p "$out"
commands="$out/commands.tsv"
printf 'file\tcommand\n' > "$commands.tmp"

run() {  # FILE ARGS...: runs raynode ARGS and records the command that wrote FILE
  local file=$1
  shift
  printf '%s\traynode %s\n' "$file" "$*" >> "$commands.tmp"
  echo "+ raynode $*" >&2
  "$raynode" "$@" > /dev/null
}

machine=(--machine ipsc2 --shadow-rays all --grid uniform)
# Table 3's node counts per database (Tetra9 and Tetra10 need 16 and 64
# nodes of 4 MiB to hold their shared memory, as on the iPSC/2).
run table3-teapot.json bench nodes teapot:8 --mode svm "${machine[@]}" --nodes 1,2,4,8,16,32,64 \
  --width "$size" --height "$size" --json "$out/table3-teapot.json"
run table3-mountain.json bench nodes mount:6 -t 6 --mode svm "${machine[@]}" --nodes 1,2,4,8,16,32,64 \
  --width "$size" --height "$size" --json "$out/table3-mountain.json"
run table3-rings4.json bench nodes rings:4 -t 1 --mode svm "${machine[@]}" --nodes 1,2,4,8,16,32,64 \
  --width "$size" --height "$size" --json "$out/table3-rings4.json"
run table3-tetra9.json bench nodes tetra:9 --mode svm "${machine[@]}" --nodes 16,32,64 \
  --width "$size" --height "$size" --json "$out/table3-tetra9.json"
run table3-tetra10.json bench nodes tetra:10 --mode svm "${machine[@]}" --nodes 64 \
  --width "$size" --height "$size" --json "$out/table3-tetra10.json"
# Figures 8-10: 32 nodes, caches from one page to all a node's free memory.
run fig8-rings4.csv sweep cache rings:4 -t 1 "${machine[@]}" --nodes 32 --quiet \
  --width "$sweep_size" --height "$sweep_size" --output "$out/fig8-rings4"
run fig8-tetra9.csv sweep cache tetra:9 "${machine[@]}" --nodes 32 --quiet \
  --width "$sweep_size" --height "$sweep_size" --output "$out/fig8-tetra9"

{
  printf 'cpu\t%s\n' "$(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo | head -n 1)"
  printf 'cores\t%s\n' "$(nproc)"
  printf 'version\t%s\n' "$("$raynode" --version)"
  printf 'date\t%s\n' "$(date -u +%Y-%m-%d)"
} > "$out/host.tsv"
mv "$commands.tmp" "$commands"
rm -f "$out"/*.plot.py  # the sweeps' plotting scripts: their PNGs are what the page shows
if [ "$out" = docs/results/paper ]; then
  python3 docs/make_results.py
else
  echo "wrote $out; docs/results.md is generated from docs/results/paper only" >&2
fi
