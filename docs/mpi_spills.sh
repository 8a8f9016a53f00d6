#!/usr/bin/env bash
# dataflow's spills on MPI ranks beside the emulator's: for each scene, rank
# count P and sending queue Q, ROUNDS runs of `mpirun -np P raynode render
# SCENE --mode dataflow --transport mpi` at WIDTH x WIDTH, each beside the
# emulator's `render --mode dataflow --nodes P --clock cpu` of the same
# queue. Per run: the fraction of ray messages spilled to the host, the
# sending queue's peak, the ray messages, the machine's wall time, and
# whether the MPI image equals the emulator's byte for byte. A ray to
# another rank's node travels on a credit (docs/architecture.md, "Ray
# credits"), so a full destination refuses it there as a full mailbox does
# in the emulator, and the paper's rule (spill only when the sender's own
# queue is full) holds on both.
#
#   [RANKS="2 4"] [QUEUES="0 64"] docs/mpi_spills.sh RAYNODE WIDTH ROUNDS SCENE... > OUT.csv
#
# Q = 0 is the default queue (all the node memory left); e.g.
# docs/mpi_spills.sh build/apps/raynode 512 3 teapot:8 rings:4
set -euo pipefail
raynode=$(realpath "$1") width=$2 rounds=$3
shift 3
# shellcheck source=docs/mpi_common.sh
. "$(dirname "$0")/mpi_common.sh"
echo "scene,ranks,send_queue,round,transport,ray_messages,spill_fraction,queue_peak,wall_s,same_image"
row() {  # SCENE P Q ROUND TRANSPORT STATS SAME
  python3 - "$@" <<'PY'
import json, sys
scene, p, q, rnd, transport, path, same = sys.argv[1:]
d = json.load(open(path))
f = d["dataflow"]
print(f'"{scene}",{p},{q},{rnd},{transport},{f["ray_messages_total"]},{f["spill_fraction"]:.5f},'
      f'{f["send_queue"]["peak"]},{d["machine"]["wall_s"]:.4f},{same}')
PY
}
for scene in "$@"; do
  for p in ${RANKS:-2 4}; do
    for q in ${QUEUES:-0 64}; do
      queue=()
      [ "$q" != 0 ] && queue=(--send-queue "$q")
      for round in $(seq "$rounds"); do
        # shellcheck disable=SC2086  # a scene may carry its SPD options ("rings:4 -t 1")
        "$raynode" render $scene --mode dataflow --nodes "$p" --clock cpu "${queue[@]}" --width "$width" \
          --height "$width" -o "$work/emu.ppm" --stats "$work/emu.json" --quiet
        # shellcheck disable=SC2086
        mpirun -np "$p" "$raynode" render $scene --mode dataflow --transport mpi "${queue[@]}" --width "$width" \
          --height "$width" -o "$work/mpi.ppm" --stats "$work/mpi.json" --quiet
        same=$(cmp -s "$work/emu.ppm" "$work/mpi.ppm" && echo yes || echo no)
        row "$scene" "$p" "$q" "$round" emulator "$work/emu.json" yes
        row "$scene" "$p" "$q" "$round" mpi "$work/mpi.json" "$same"
      done
    done
  done
done
