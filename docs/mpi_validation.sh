#!/usr/bin/env bash
# A first validation of the emulator against real execution: the MPI
# transport's latency and bandwidth measured on this machine (bench mpi),
# given to the emulator as a machine description; then, per scene, mode and
# rank count p, the measured wall-clock speedup of p MPI ranks over 1
# (machine.wall_s of render --transport mpi) beside the emulator's predicted
# one (virtual T_p of render --nodes 1 and p with that description), under
# the CPU clock (each node thread's CPU time, on this host's cores shared
# with the emulator's scheduler) and under the model clock (the work's cost
# model: deterministic). efficiency = T_1 / (p x T_p).
#
# Each of REPEATS rounds runs 1 and p ranks, then the emulator's 1 and p
# nodes under each clock, back to back, so that a round sees one state of
# the host; the CSV gives the medians over the rounds of the times and of
# the rounds' own efficiencies (a slow phase of a shared machine spans
# whole runs, and the least times of separate series would pair a fast
# T_1 with a slow T_p).
#
#   [RANKS="2 4 ..."] docs/mpi_validation.sh RAYNODE WIDTH REPEATS SCENE... > OUT.csv
#
# RANKS defaults to 2. e.g. docs/mpi_validation.sh build/apps/raynode 512 7 teapot:8 rings:4
set -euo pipefail
raynode=$(realpath "$1") width=$2 repeats=$3
shift 3
# shellcheck source=docs/mpi_common.sh
. "$(dirname "$0")/mpi_common.sh"
mpirun -np 2 "$raynode" bench mpi --machine-out "$work/mpi.json" --json "$work/bench.json" > /dev/null
latency=$(json_value "$work/mpi.json" network latency_s) per_byte=$(json_value "$work/mpi.json" network per_byte_s)

ranks=${RANKS:-2}
echo "scene,mode,width,latency_us,per_byte_ns,ranks,rounds,t1_wall_s,tp_wall_s,speedup_measured,efficiency_measured,clock,t1_predicted_s,tp_predicted_s,efficiency_predicted,error_points"
mpi_wall() {  # RANKS SCENE MODE: machine.wall_s of one MPI render
  mpirun -np "$1" "$raynode" render "$2" --mode "$3" --transport mpi --width "$width" --height "$width" \
    -o "$work/o.ppm" --stats "$work/s.json" --quiet
  json_value "$work/s.json" machine wall_s
}
emulated() {  # NODES SCENE MODE CLOCK: the emulator's T_p
  "$raynode" render "$2" --mode "$3" --nodes "$1" --machine "$work/mpi.json" --clock "$4" \
    --width "$width" --height "$width" -o "$work/o.ppm" --stats "$work/s.json" --quiet
  json_value "$work/s.json" machine parallel_time_s
}
for scene in "$@"; do
  for mode in svm replicated; do
    for p in $ranks; do
      rounds=$work/rounds.csv
      : > "$rounds"
      for _ in $(seq "$repeats"); do
        echo "$(mpi_wall 1 "$scene" "$mode"),$(mpi_wall "$p" "$scene" "$mode"),$(emulated 1 "$scene" "$mode" cpu),$(emulated "$p" "$scene" "$mode" cpu),$(emulated 1 "$scene" "$mode" model),$(emulated "$p" "$scene" "$mode" model)" >> "$rounds"
      done
      python3 - "$scene" "$mode" "$width" "$p" "$latency" "$per_byte" "$rounds" <<'PY'
import statistics, sys
scene, mode, width, p, lat, pb, path = sys.argv[1:8]
n, lat, pb = int(p), float(lat), float(pb)
rows = [list(map(float, line.split(","))) for line in open(path) if line.strip()]
med = statistics.median
w1, wp = med(r[0] for r in rows), med(r[1] for r in rows)
em = med(r[0] / (n * r[1]) for r in rows)
for clock, i in (("cpu", 2), ("model", 4)):
    p1, pp = med(r[i] for r in rows), med(r[i + 1] for r in rows)
    ep = med(r[i] / (n * r[i + 1]) for r in rows)
    print(f'"{scene}",{mode},{width},{lat * 1e6:.2f},{pb * 1e9:.3f},{n},{len(rows)},{w1:.4f},{wp:.4f},'
          f'{med(r[0] / r[1] for r in rows):.3f},{em:.4f},{clock},{p1:.4f},{pp:.4f},{ep:.4f},{(ep - em) * 100:.1f}')
PY
    done
  done
done
