#!/usr/bin/env bash
# A first validation of the emulator against real execution: the MPI
# transport measured on this machine (bench mpi), given to the emulator as a
# machine description; then, per scene, mode and rank count p, the measured
# wall-clock speedup of p MPI ranks over 1 (machine.wall_s of render
# --transport mpi) beside the emulator's predicted one (virtual T_p of
# render --nodes 1 and p with that description). Three predictions:
#   cpu          the CPU clock (each node thread's CPU time, on this host's
#                cores shared with the emulator's scheduler), with the
#                transport's latency and per-byte time only;
#   model        the model clock (the work's cost model: deterministic),
#                the same figures;
#   model-host   the model clock with the whole description, all of it
#                measured on this host by bench mpi: also this host's unit
#                costs (bench cost-model's fit), and what a node's work
#                costs on ranks that share this machine, from a probe
#                (teapot:8 at 256x256, replicated): the co-running slowdown
#                and the time of a look for mail (corun_slowdown, network
#                poll_s). The probe's scene is fixed: for any other scene
#                the prediction comes from the machine's figures alone.
# efficiency = T_1 / (p x T_p).
#
# Each of REPEATS rounds runs 1 and p ranks, then the emulator's 1 and p
# nodes under each prediction, back to back, so that a round sees one state
# of the host; the CSV gives the medians over the rounds of the times and of
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

ranks=${RANKS:-2}
echo "scene,mode,width,latency_us,per_byte_ns,ranks,rounds,t1_wall_s,tp_wall_s,speedup_measured,efficiency_measured,clock,t1_predicted_s,tp_predicted_s,efficiency_predicted,error_points,corun_slowdown,poll_us"
mpi_wall() {  # RANKS SCENE MODE: machine.wall_s of one MPI render
  mpirun -np "$1" "$raynode" render "$2" --mode "$3" --transport mpi --width "$width" --height "$width" \
    -o "$work/o.ppm" --stats "$work/s.json" --quiet
  json_value "$work/s.json" machine wall_s
}
emulated() {  # NODES SCENE MODE CLOCK DESCRIPTION: the emulator's T_p
  "$raynode" render "$2" --mode "$3" --nodes "$1" --machine "$5" --clock "$4" \
    --width "$width" --height "$width" -o "$work/o.ppm" --stats "$work/s.json" --quiet
  json_value "$work/s.json" machine parallel_time_s
}
for p in $ranks; do
  # The whole description, and the transport's latency and per-byte time alone.
  mpirun -np "$p" "$raynode" bench mpi --machine-out "$work/full$p.json" > /dev/null
  python3 - "$work/full$p.json" "$work/link$p.json" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
m.pop("corun_slowdown")
m.pop("cost_model")
m["network"].pop("poll_s")
m["network"].pop("seconds_per_ray")
json.dump(m, open(sys.argv[2], "w"))
PY
done
for scene in "$@"; do
  for p in $ranks; do
    full=$work/full$p.json link=$work/link$p.json
    latency=$(json_value "$full" network latency_s) per_byte=$(json_value "$full" network per_byte_s)
    corun=$(json_value "$full" corun_slowdown) poll=$(json_value "$full" network poll_s)
    for mode in svm replicated; do
      rounds=$work/rounds.csv
      : > "$rounds"
      for _ in $(seq "$repeats"); do
        echo "$(mpi_wall 1 "$scene" "$mode"),$(mpi_wall "$p" "$scene" "$mode"),$(emulated 1 "$scene" "$mode" cpu "$link"),$(emulated "$p" "$scene" "$mode" cpu "$link"),$(emulated 1 "$scene" "$mode" model "$link"),$(emulated "$p" "$scene" "$mode" model "$link"),$(emulated 1 "$scene" "$mode" model "$full"),$(emulated "$p" "$scene" "$mode" model "$full")" >> "$rounds"
      done
      python3 - "$scene" "$mode" "$width" "$p" "$latency" "$per_byte" "$rounds" "$corun" "$poll" <<'PY'
import statistics, sys
scene, mode, width, p, lat, pb, path, corun, poll = sys.argv[1:10]
n, lat, pb, corun, poll = int(p), float(lat), float(pb), float(corun), float(poll)
rows = [list(map(float, line.split(","))) for line in open(path) if line.strip()]
med = statistics.median
w1, wp = med(r[0] for r in rows), med(r[1] for r in rows)
em = med(r[0] / (n * r[1]) for r in rows)
# (prediction, its T_1 column (T_p the next), the co-running slowdown and look for mail it charges)
for clock, i, s, q in (("cpu", 2, 1.0, 0.0), ("model", 4, 1.0, 0.0), ("model-host", 6, corun, poll)):
    p1, pp = med(r[i] for r in rows), med(r[i + 1] for r in rows)
    ep = med(r[i] / (n * r[i + 1]) for r in rows)
    print(f'"{scene}",{mode},{width},{lat * 1e6:.2f},{pb * 1e9:.3f},{n},{len(rows)},{w1:.4f},{wp:.4f},'
          f'{med(r[0] / r[1] for r in rows):.3f},{em:.4f},{clock},{p1:.4f},{pp:.4f},{ep:.4f},{(ep - em) * 100:.1f},'
          f'{s:.3f},{q * 1e6:.3f}')
PY
    done
  done
done
