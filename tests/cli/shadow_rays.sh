#!/usr/bin/env bash
# --shadow-rays all in every mode: the same image as --shadow-rays facing,
# and exactly the facing run's shadow rays plus the ones it skipped because
# the light was behind the surface (the paper's ray count, core/shade.h).
#
#   shadow_rays.sh RAYNODE WORKDIR
set -uo pipefail
raynode=$(realpath "$1") workdir=$2
rm -rf "$workdir" && mkdir -p "$workdir" && cd "$workdir" || exit 2

fail=0
count() {  # FILE KEY: the first "KEY": N in a --stats file
  sed -n "s/^ *\"$2\": \([0-9]*\),\{0,1\}$/\1/p" "$1" | head -n 1
}
for mode in sequential replicated svm dataflow; do
  nodes=()
  [ "$mode" = sequential ] || nodes=(--nodes 3)
  for rule in facing all; do
    if ! timeout --kill-after=5 100 "$raynode" render rings:2 --width 40 --height 32 --quiet --timeout 60 \
        --mode "$mode" "${nodes[@]}" --shadow-rays "$rule" -o "$mode-$rule.png" --stats "$mode-$rule.json" \
        2>"$mode-$rule.err"; then
      echo "FAIL: $mode --shadow-rays $rule:"; cat "$mode-$rule.err"; fail=1; continue
    fi
  done
  [ -e "$mode-facing.json" ] && [ -e "$mode-all.json" ] || continue
  shadow_f=$(count "$mode-facing.json" shadow) back_f=$(count "$mode-facing.json" shadow_backfacing)
  shadow_a=$(count "$mode-all.json" shadow) back_a=$(count "$mode-all.json" shadow_backfacing)
  echo "$mode: facing $shadow_f shadow rays + $back_f behind; all $shadow_a shadow rays + $back_a behind"
  if [ -z "$shadow_f" ] || [ -z "$back_f" ] || [ "${back_f:-0}" -eq 0 ]; then
    echo "FAIL: $mode: no shadow counts, or no light behind a surface to test with"; fail=1; continue
  fi
  [ "$shadow_a" = $((shadow_f + back_f)) ] || { echo "FAIL: $mode: all != facing + behind"; fail=1; }
  [ "$back_a" = 0 ] || { echo "FAIL: $mode: all still skipped $back_a"; fail=1; }
  # dataflow sums contributions in arrival order (last bits may differ): its
  # own two runs are compared by the counts only.
  if [ "$mode" != dataflow ]; then
    cmp -s "$mode-facing.png" "$mode-all.png" || { echo "FAIL: $mode: the images differ"; fail=1; }
    cmp -s sequential-facing.png "$mode-all.png" || { echo "FAIL: $mode: differs from sequential"; fail=1; }
  fi
done
exit $fail
