#!/usr/bin/env bash
# What a node's work costs on MPI ranks that share this machine, as bench
# mpi's probe measures it, over several probe scenes and sizes: one node
# alone, beside the other ranks' nodes, and one node per rank over MPI
# (busy CPU seconds, medians of the probe's rounds); the co-running slowdown
# and the time per look for mail that the probe derives; and, for
# comparison, the whole cost on ranks as one factor (on ranks / alone).
#
#   [RANKS=N] docs/mpi_probe.sh RAYNODE SCENE:SIZE... > OUT.csv
#
# e.g. docs/mpi_probe.sh build/apps/raynode teapot:8:256 teapot:8:512 rings:4:256 rings:4:512
set -euo pipefail
raynode=$(realpath "$1")
shift
# shellcheck source=docs/mpi_common.sh
. "$(dirname "$0")/mpi_common.sh"
ranks=${RANKS:-2}
echo "probe,size,ranks,rounds,alone_s,shared_s,on_ranks_s,mail_checks,corun_slowdown,poll_us,on_ranks_over_alone"
for case in "$@"; do
  scene=${case%:*} size=${case##*:}
  mpirun -np "$ranks" "$raynode" bench mpi --sizes 8,1024 --repeats 100 --probe "$scene" --probe-size "$size" \
    --json "$work/b.json" > /dev/null
  python3 - "$work/b.json" "$ranks" <<'PY'
import json, sys
p = json.load(open(sys.argv[1]))["probe"]
print(f'"{p["scene"]}",{p["size"]},{sys.argv[2]},{p["rounds"]},{p["alone_s"]:.4f},{p["shared_s"]:.4f},'
      f'{p["transport_s"]:.4f},{p["mail_checks"]:.0f},{p["corun_slowdown"]:.3f},{p["poll_s"] * 1e6:.3f},'
      f'{p["transport_s"] / p["alone_s"]:.3f}')
PY
done
