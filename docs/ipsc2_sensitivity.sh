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
      python3 - "$so" "$sv" "$c" > "$work/m.json" <<'PY'
import json, sys
so, sv, c = float(sys.argv[1]) * 1e-3, float(sys.argv[2]) * 1e-3, sys.argv[3] == "true"
start = 1024 / 0.9e6 - 1024 / 2.75e6  # the paper's start-up: 1 KiB at 0.9 MB/s, 2.75 MB/s peak
print(json.dumps({"name": "ipsc2-sensitivity", "node_memory": "4MiB", "page_size": 1024, "topology": "hypercube",
                  "clock": "model",
                  "network": {"latency_s": start - so, "per_byte_s": 1 / 2.75e6, "per_hop_s": 10e-6,
                              "service_s": sv, "fault_s": 100e-6, "send_overhead_s": so,
                              "seconds_per_ray": 11522.0 / 1397473.0, "contention": c}}))
PY
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
