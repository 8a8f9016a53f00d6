#!/usr/bin/env bash
# The node modes on MPI ranks (label `mpi`): `mpirun -np N raynode render
# SCENE --mode M --transport mpi` for N = 1..4 must give the sequential image:
# byte for byte for replicated and svm, within one 8-bit step per channel for
# dataflow (it adds contributions in arrival order); svm also with one-sided
# page reads (--page-fetch get; said to be skipped where this MPI has no
# one-sided support between ranks). Only rank 0 writes.
#
#   mpi_render.sh RAYNODE MPIEXEC WORKDIR SCENE [render options...]
set -uo pipefail
raynode=$(realpath "$1") mpiexec=$2 workdir=$3 scene=$4
shift 4
rm -rf "$workdir" && mkdir -p "$workdir" && cd "$workdir" || exit 2
# Root in CI containers: Open MPI refuses to start as root without these.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
args=("$scene" --width 40 --height 32 --quiet --timeout 100 "$@")
fail=0
# mpirun -np N raynode ARGS..., its output in LOG. Open MPI 4.1 now and then
# reports a rank that ended after MPI_Finalize as "with PID 0 ... exiting
# improperly" (a race in its launcher's shutdown, seen under load); such a run
# is tried again, at most twice, and said so. A rank that really skips
# MPI_Finalize fails every try, and a run where a rank printed an error is
# never retried (the other ranks' "stopped by SIGTERM", from mpirun's clean-up
# after the report, is no error of theirs).
run_ranks() {
  local np=$1 log=$2 try
  shift 2
  for try in 1 2 3; do
    timeout --kill-after=5 120 "$mpiexec" -np "$np" "$raynode" "$@" >"$log" 2>&1 && return 0
    grep -q "with PID 0 on" "$log" && grep -q "exiting improperly" "$log" && ! grep -q "^raynode: error" "$log" || return 1
    [ "$try" = 3 ] && return 1
    echo "NOTE: -np $np try $try: Open MPI reported a rank with PID 0 exiting improperly; trying again"
  done
  return 1
}
"$raynode" render "${args[@]}" --mode sequential -o ref.ppm || { echo "FAIL: the sequential render"; exit 1; }
for np in 1 2 3 4; do
  for mode in replicated svm dataflow svm-get; do
    out="$mode$np.ppm"
    how=(--mode "$mode")
    [ "$mode" = svm-get ] && how=(--mode svm --page-fetch get)
    if ! run_ranks "$np" "$mode$np.log" render "${args[@]}" "${how[@]}" --transport mpi -o "$out" --stats "$mode$np.json"; then
      if [ "$mode" = svm-get ] && grep -q "MPI_Win_create" "$mode$np.log"; then
        echo "SKIP: -np $np --page-fetch get: no one-sided MPI between these ranks here:"
        grep -m1 "MPI_Win_create" "$mode$np.log"
        rm -f "$mode$np.log"
        continue
      fi
      echo "FAIL: mpirun -np $np render ${how[*]} exited non-zero:"
      cat "$mode$np.log"
      fail=1
      continue
    fi
    [ -s "$out" ] || { echo "FAIL: -np $np --mode $mode wrote no image"; fail=1; continue; }
    grep -q '"transport": "mpi"' "$mode$np.json" || { echo "FAIL: $mode$np.json does not name the mpi transport"; fail=1; }
    # Pages fetched by request, or read one-sidedly without a request.
    # On ranks, work grants default to half a submap (one real round trip each).
    if [ "$mode" != dataflow ] && ! grep -q '"work_grants": "half"' "$mode$np.json"; then
      echo "FAIL: $mode on $np ranks: work grants are not half by default"; fail=1
    fi
    if [ "$np" -gt 1 ] && [ "$mode" = svm ] && ! grep -q '"page_requests": [1-9]' "$mode$np.json"; then
      echo "FAIL: -np $np svm sent no page request"; fail=1
    fi
    if [ "$mode" = svm-get ] && grep -q '"page_requests": [1-9]' "$mode$np.json"; then
      echo "FAIL: -np $np svm --page-fetch get sent page requests"; fail=1
    fi
    if [ "$np" -gt 1 ] && [ "$mode" = svm-get ] && ! grep -q '"misses": [1-9]' "$mode$np.json"; then
      echo "FAIL: -np $np svm --page-fetch get had no page fault"; fail=1
    fi
    count=$(grep -c '"wall_s"' "$mode$np.json")
    [ "$count" -ge "$((np + 1))" ] || { echo "FAIL: $mode$np.json has $count wall_s entries for $np ranks"; fail=1; }
    if [ "$mode" = dataflow ]; then
      # cmp -l: offset and both bytes (octal) of every differing byte.
      worst=$(cmp -l ref.ppm "$out" | awk 'function oct(s,  n, i) { n = 0; for (i = 1; i <= length(s); i++) n = n * 8 + substr(s, i, 1); return n }
        { a = oct($2); b = oct($3); d = a > b ? a - b : b - a; if (d > m) m = d } END { print m + 0 }')
      [ "$(stat -c %s ref.ppm)" = "$(stat -c %s "$out")" ] && [ "$worst" -le 1 ] ||
        { echo "FAIL: -np $np dataflow differs from the sequential image (worst step $worst)"; fail=1; }
    elif ! cmp -s ref.ppm "$out"; then
      echo "FAIL: -np $np --mode $mode differs from the sequential image"
      fail=1
    fi
  done
done
extra=$(ls | grep -v -E '^(ref\.ppm|(replicated|svm|dataflow|svm-get)[1-4]\.(ppm|json|log))$')
[ -z "$extra" ] || { echo "FAIL: files no rank should write: $extra"; fail=1; }
[ "$fail" = 0 ] && echo "PASS: the MPI renders equal the sequential image"
exit "$fail"
