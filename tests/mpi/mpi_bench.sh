#!/usr/bin/env bash
# `raynode bench mpi` under mpirun -np 2 (label `mpi`): the machine
# description it writes holds the transport's latency and per-byte time, the
# probe's co-running slowdown (>= 1) and time per look for mail (>= 0), this
# host's seconds per ray and every unit cost of the model clock fitted
# here; the JSON holds every probe round; and a
# render with that description charges them under the model clock: its
# nodes' busy time is that of the same render without them, times the
# slowdown, plus a look's time per look for mail.
#
#   mpi_bench.sh RAYNODE MPIEXEC WORKDIR
set -uo pipefail
raynode=$(realpath "$1") mpiexec=$2 workdir=$3
rm -rf "$workdir" && mkdir -p "$workdir" && cd "$workdir" || exit 2
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
timeout --kill-after=5 120 "$mpiexec" -np 2 "$raynode" bench mpi --sizes 8,4096 --repeats 20 --probe teapot:2 \
  --probe-size 24 --probe-rounds 3 --machine-out m.json --json b.json > log.txt 2>&1 ||
  { cat log.txt; echo "FAIL: bench mpi"; exit 1; }
grep -q "^probe: teapot:2 at 24x24, replicated, median of 3 rounds" log.txt ||
  { cat log.txt; echo "FAIL: no probe line"; exit 1; }
python3 - <<'PY' || { echo "FAIL: the machine description or the JSON"; exit 1; }
import json
m = json.load(open("m.json"))
b = json.load(open("b.json"))
n = m["network"]
assert n["latency_s"] > 0 and n["seconds_per_ray"] > 0 and n["poll_s"] >= 0, m
p = b["probe"]
assert p["rounds"] == 3 and len(p["round_slowdowns"]) == 3 and len(p["round_poll_s"]) == 3, p
assert p["alone_s"] > 0 and p["shared_s"] > 0 and p["transport_s"] > 0 and p["mail_checks"] > 0, p
assert m["corun_slowdown"] == max(1.0, p["corun_slowdown"]) and n["poll_s"] == p["poll_s"], (m, p)
c = m["cost_model"]  # this host's unit costs, every one named
assert len(c) == 14 and all(v >= 0 for v in c.values()) and c["primary_ray"] > 0 and c["triangle_test"] > 0, c
# A description with figures large enough to see, for the render below.
m["corun_slowdown"] = 1.5
n["poll_s"] = 1e-4
json.dump(m, open("big.json", "w"))
m.pop("corun_slowdown")
n.pop("poll_s")
json.dump(m, open("bare.json", "w"))
PY
# Under the model clock, with and without the description's two figures.
for d in big bare; do
  "$raynode" render teapot:2 --width 24 --height 24 --mode replicated --nodes 2 --machine $d.json --clock model \
    --calibrate off -o $d.ppm --stats $d.json.stats --quiet || { echo "FAIL: render with the $d description"; exit 1; }
done
cmp -s big.ppm bare.ppm || { echo "FAIL: the figures changed the image"; exit 1; }
python3 - <<'PY' || { echo "FAIL: the model clock did not charge the description's figures"; exit 1; }
import json
big = json.load(open("big.json.stats"))["machine"]
bare = json.load(open("bare.json.stats"))["machine"]
assert big["corun_slowdown"] == 1.5 and bare["corun_slowdown"] == 1.0, (big, bare)
# The same rays either way (the grants may differ, as the charges move the virtual times), so the same
# metered work: the rest is the looks for mail, at poll_s scaled to the model clock's seconds by the
# description's seconds_per_ray.
checks = big["total"]["mail_checks"]
assert checks > 0, big["total"]
per_look = (big["total"]["time"]["busy_s"] - 1.5 * bare["total"]["time"]["busy_s"]) / checks
assert 1e-6 < per_look < 1e-2, per_look
PY
echo "bench mpi: corun_slowdown $(python3 -c 'import json; print(json.load(open("m.json"))["corun_slowdown"])')"
