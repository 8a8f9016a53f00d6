#!/usr/bin/env bash
# Wall-clock scaling of the node programs on MPI ranks of one machine: for
# each round, mode and rank count, one `mpirun -np P raynode render SCENE
# --mode M --transport mpi` at WIDTH x WIDTH, its machine wall time
# (machine.wall_s of --stats: the frame, from the ranks' start to the
# image's assembly), the slowest node's wall time, and the nodes' real
# seconds blocked for mail, summed over the nodes (per_node[].time:
# idle_wall_s, and communication_wall_s for pages and work grants).
#
#   docs/mpi_scaling.sh RAYNODE SCENE WIDTH ROUNDS RANKS... > OUT.csv
#
# e.g. docs/mpi_scaling.sh build/apps/raynode teapot:8 1024 3 1 2 4 8 15
# (on 16 cores: 15 ranks leave a core to the host and receiving threads).
set -euo pipefail
raynode=$(realpath "$1") scene=$2 width=$3 rounds=$4
shift 4
# shellcheck source=docs/mpi_common.sh
. "$(dirname "$0")/mpi_common.sh"
echo "round,mode,ranks,wall_s,node_wall_max_s,idle_wall_sum_s,communication_wall_sum_s"
for round in $(seq "$rounds"); do
  for mode in svm replicated; do
    for p in "$@"; do
      mpirun -np "$p" "$raynode" render "$scene" --mode "$mode" --transport mpi --width "$width" --height "$width" \
        -o "$work/o.ppm" --stats "$work/s.json" --quiet
      python3 - "$work/s.json" "$round" "$mode" "$p" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
nodes = d["per_node"]
print(f"{sys.argv[2]},{sys.argv[3]},{sys.argv[4]},{d['machine']['wall_s']:.4f},{max(n['wall_s'] for n in nodes):.4f},"
      f"{sum(n['time']['idle_wall_s'] for n in nodes):.4f},{sum(n['time']['communication_wall_s'] for n in nodes):.4f}")
PY
    done
  done
done
