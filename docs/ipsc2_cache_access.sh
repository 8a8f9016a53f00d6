#!/usr/bin/env bash
# How svm's efficiency against node count moves with a cost no source gives:
# the work of each access to a cached page (network.cache_access_s: a
# software shared virtual memory's cache lookup and LRU recency update,
# which home pages and a one-node run never pay). Each point is a machine
# description (--machine FILE) of the ipsc2 preset's figures in iPSC/2
# seconds with cache_access_s set; the runs are Table 3's (svm,
# --shadow-rays all, --grid uniform).
#
#   docs/ipsc2_cache_access.sh RAYNODE "SCENE" WIDTH NODES COSTS_US > OUT.csv
#
# NODES is bench nodes' list (1,2,4,...), COSTS_US the costs in iPSC/2
# microseconds, comma-separated; e.g.
#   docs/ipsc2_cache_access.sh build/apps/raynode teapot:8 512 1,2,4,8,16,32,64 0,10,20,40
set -euo pipefail
raynode=$1 scene=$2 width=$3 nodes=$4 costs=$5
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "scene,width,cache_access_us,nodes,parallel_time_s,efficiency,cache_page_accesses,accesses"
for us in ${costs//,/ }; do
  python3 "$(dirname "$0")/ipsc2_machine.py" ipsc2-cache-access "cache_access_s=${us}e-6" > "$work/m.json"
  # shellcheck disable=SC2086  # the scene spec may carry options (rings:4 -t 1)
  "$raynode" bench nodes $scene --mode svm --machine "$work/m.json" --shadow-rays all --grid uniform \
    --nodes "$nodes" --width "$width" --height "$width" --json "$work/o.json" > /dev/null
  python3 - "$work/o.json" "$scene" "$width" "$us" <<'PY'
import json, sys
for r in json.load(open(sys.argv[1]))["rows"]:
    print(f'"{sys.argv[2]}",{sys.argv[3]},{sys.argv[4]},{r["nodes"]},{r["parallel_time_s"]:.6g},'
          f'{r["efficiency"]:.4f},{r["cache_page_accesses"]},{r["accesses"]}')
PY
done
