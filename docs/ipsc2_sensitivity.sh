#!/usr/bin/env bash
# How sensitive svm's efficiency is to the iPSC/2 costs no source gives:
# the sender's CPU time per message (send_overhead_s), the home node's time
# to serve a page request (service_s) and link contention. Each point is a
# machine description (--machine FILE) of the ipsc2 preset's figures in
# iPSC/2 seconds with one of these changed; efficiency = T_1 / (N x T_p).
#
#   docs/ipsc2_sensitivity.sh RAYNODE "SCENE" WIDTH NODES > OUT.csv
#
# e.g. docs/ipsc2_sensitivity.sh build/apps/raynode teapot:8 512 64
set -euo pipefail
raynode=$1 scene=$2 width=$3 nodes=$4
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "scene,width,nodes,send_overhead_ms,service_ms,contention,t1_s,parallel_time_s,efficiency"
for so in 0 0.35 0.765; do
  for sv in 0.1 0.5 1.0; do
    for c in true false; do
      python3 "$(dirname "$0")/ipsc2_machine.py" ipsc2-sensitivity "send_overhead_s=${so}e-3" \
        "service_s=${sv}e-3" "contention=$c" > "$work/m.json"
      # shellcheck disable=SC2086  # the scene spec may carry options (rings:4 -t 1)
      "$raynode" bench nodes $scene --mode svm --machine "$work/m.json" --nodes "1,$nodes" --width "$width" \
        --height "$width" --json "$work/o.json" > /dev/null
      python3 - "$work/o.json" "$scene" "$width" "$nodes" "$so" "$sv" "$c" <<'PY'
import json, sys
rows = {r["nodes"]: r for r in json.load(open(sys.argv[1]))["rows"]}
n = int(sys.argv[4])
print(f'"{sys.argv[2]}",{sys.argv[3]},{n},{sys.argv[5]},{sys.argv[6]},{sys.argv[7]},'
      f'{rows[1]["parallel_time_s"]:.6g},{rows[n]["parallel_time_s"]:.6g},{rows[n]["efficiency"]:.4f}')
PY
    done
  done
done
