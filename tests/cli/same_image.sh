#!/usr/bin/env bash
# Determinism through the CLI: one scene rendered in sequential, shared,
# replicated and svm modes, with several node counts, caches and network
# models, twice each, must give byte-identical PNG files. (dataflow adds
# contributions in arrival order, so its floats may differ in the last bits:
# its tolerance of 1e-5 is checked by tests/robustness and tests/dataflow.)
#
#   same_image.sh RAYNODE WORKDIR
set -uo pipefail
raynode=$(realpath "$1") workdir=$2
rm -rf "$workdir" && mkdir -p "$workdir" && cd "$workdir" || exit 2

scene=(rings:2 --width 48 --height 40 --quiet --timeout 60)  # the watchdog names a hang's state
fail=0
render() {  # NAME ARGS...
  local name=$1
  shift
  timeout --kill-after=5 100 "$raynode" render "${scene[@]}" -o "$name.png" "$@" 2>"$name.err"
  local rc=$?
  if [ "$rc" != 0 ]; then
    echo "FAIL: render $name ($*) exited $rc:"
    cat "$name.err"
    fail=1
  fi
}

render ref --mode sequential
for run in 1 2; do
  render "seq$run" --mode sequential
  render "shared$run" --mode shared
  for n in 1 3 16; do render "rep${n}_$run" --mode replicated --nodes "$n" --network ipsc2 --network-scale 1e-4; done
  render "rep7os_$run" --mode replicated --nodes 7 --schedule-window -1
  for n in 2 7; do
    render "svm${n}_$run" --mode svm --nodes "$n" --cache 1 --page-size 256 --network ipsc2 --network-scale 1e-4
  done
  render "svm5all_$run" --mode svm --nodes 5 --topology ring
  # The grid walk without empty-space jumps finds the same hits.
  render "seqnoskip_$run" --mode sequential --skip-empty off
  render "svm3noskip_$run" --mode svm --nodes 3 --cache 2 --skip-empty off
  # Mail served by the scheduler instead of per message: same images.
  render "rep7mail_$run" --mode replicated --nodes 7 --mail-wakeups scheduled
  render "svm4mail_$run" --mode svm --nodes 4 --cache 2 --mail-wakeups scheduled
done

[ -s ref.png ] || { echo "FAIL: no reference image"; exit 1; }
count=0
for f in *.png; do
  [ "$f" = ref.png ] && continue
  count=$((count + 1))
  if ! cmp -s ref.png "$f"; then
    echo "FAIL: $f differs from the sequential image"
    fail=1
  fi
done
echo "compared $count images with the sequential one"
[ "$count" -ge 26 ] || { echo "FAIL: only $count images rendered"; fail=1; }
[ "$fail" = 0 ] && echo "PASS"
exit "$fail"
