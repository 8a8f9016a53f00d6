#!/usr/bin/env bash
# Behaviour kept across changes to the command line and the modes: renders
# rings:1 in MODE and checks that the --stats JSON still has every key the
# golden list names (tests/cli/golden/stats_keys_MODE.txt, written from an
# earlier build: keys may be added, never lost), and that the image equals
# sequential's byte for byte (dataflow: its own summation order, so only the
# keys).
#
#   stats_keys.sh RAYNODE GOLDEN_DIR WORKDIR MODE
set -euo pipefail
raynode=$1 golden=$2 work=$3 mode=$4
rm -rf "$work" && mkdir -p "$work" && cd "$work"
nodes=1
case $mode in replicated|svm|dataflow) nodes=3 ;; esac
"$raynode" render rings:1 --width 8 --height 8 -o seq.png --quiet
"$raynode" render rings:1 --width 8 --height 8 -o "$mode.png" --stats "$mode.json" --aov depth \
  --mode "$mode" --nodes "$nodes" --quiet
grep -o '"[A-Za-z0-9_.-]*":' "$mode.json" | tr -d '":' | LC_ALL=C sort -u > keys.txt
LC_ALL=C sort -u "$golden/stats_keys_$mode.txt" > golden.txt
missing=$(LC_ALL=C comm -23 golden.txt keys.txt)
if [ -n "$missing" ]; then
  echo "FAIL: --stats of mode $mode lost keys:"; echo "$missing"; exit 1
fi
if [ "$mode" != dataflow ]; then
  cmp seq.png "$mode.png" || { echo "FAIL: mode $mode's image differs from sequential's"; exit 1; }
fi
echo "ok: $mode keeps its $(wc -l < golden.txt) golden keys"
