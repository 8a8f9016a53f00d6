#!/usr/bin/env bash
# A first validation of the emulator against real execution: the MPI
# transport's latency and bandwidth measured on this machine (bench mpi),
# given to the emulator as a machine description; then, per scene, mode and
# rank count p, the measured wall-clock speedup of p MPI ranks over 1
# (machine.wall_s of render --transport mpi, best of REPEATS) beside the
# emulator's predicted one (virtual T_p of render --nodes 1 and p with that
# description, best of REPEATS), under the CPU clock (each node thread's CPU
# time, on this host's cores shared with the emulator's scheduler) and under
# the model clock (the work's cost model: deterministic).
# efficiency = T_1 / (p x T_p).
#
#   [RANKS="2 4 ..."] docs/mpi_validation.sh RAYNODE WIDTH REPEATS SCENE... > OUT.csv
#
# RANKS defaults to 2. e.g. docs/mpi_validation.sh build/apps/raynode 512 5 teapot:8 rings:4
set -euo pipefail
raynode=$(realpath "$1") width=$2 repeats=$3
shift 3
# shellcheck source=docs/mpi_common.sh
. "$(dirname "$0")/mpi_common.sh"
mpirun -np 2 "$raynode" bench mpi --machine-out "$work/mpi.json" --json "$work/bench.json" > /dev/null
latency=$(json_value "$work/mpi.json" network latency_s) per_byte=$(json_value "$work/mpi.json" network per_byte_s)

best() {  # the least of the numbers on stdin
  sort -g | head -1
}
ranks=${RANKS:-2}
echo "scene,mode,width,latency_us,per_byte_ns,ranks,t1_wall_s,tp_wall_s,speedup_measured,efficiency_measured,clock,t1_predicted_s,tp_predicted_s,efficiency_predicted,error_points"
for scene in "$@"; do
  for mode in svm replicated; do
    declare -A wall pred
    for n in 1 $ranks; do
      wall[$n]=$(for _ in $(seq "$repeats"); do
        mpirun -np "$n" "$raynode" render "$scene" --mode "$mode" --transport mpi --width "$width" --height "$width" \
          -o "$work/o.ppm" --stats "$work/s.json" --quiet
        json_value "$work/s.json" machine wall_s
      done | best)
      for clock in cpu model; do
        pred[$clock$n]=$(for _ in $(seq "$repeats"); do
          "$raynode" render "$scene" --mode "$mode" --nodes "$n" --machine "$work/mpi.json" --clock "$clock" \
            --width "$width" --height "$width" -o "$work/o.ppm" --stats "$work/s.json" --quiet
          json_value "$work/s.json" machine parallel_time_s
        done | best)
      done
    done
    for p in $ranks; do
      for clock in cpu model; do
        python3 - "$scene" "$mode" "$width" "$clock" "$p" "$latency" "$per_byte" "${wall[1]}" "${wall[$p]}" \
          "${pred[${clock}1]}" "${pred[$clock$p]}" <<'PY'
import sys
scene, mode, width, clock, p = sys.argv[1:6]
lat, pb, w1, wp, p1, pp = map(float, sys.argv[6:12])
n = int(p)
em, ep = w1 / (n * wp), p1 / (n * pp)
print(f'"{scene}",{mode},{width},{lat * 1e6:.2f},{pb * 1e9:.3f},{n},{w1:.4f},{wp:.4f},{w1 / wp:.3f},{em:.4f},{clock},'
      f'{p1:.4f},{pp:.4f},{ep:.4f},{(ep - em) * 100:.1f}')
PY
      done
    done
  done
done
