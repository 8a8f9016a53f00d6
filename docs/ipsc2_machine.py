#!/usr/bin/env python3
"""The ipsc2 preset (nodes/network.cpp) as a machine description for
--machine FILE, in iPSC/2 seconds, with some network figures changed:

    python3 docs/ipsc2_machine.py NAME [FIGURE=VALUE ...] > machine.json

FIGURE is a key of the description's "network" object (send_overhead_s,
service_s, cache_access_s, contention, ...); VALUE a number of iPSC/2
seconds, or true/false. The sweeps of docs/results.md build their points
with it (docs/ipsc2_sensitivity.sh, docs/ipsc2_cache_access.sh)."""
import json
import sys

SEND_OVERHEAD_S = 350e-6  # the preset's sender CPU time per message (kIpsc2SendOverheadS)
PEAK_B_PER_S, RATE_1K_B_PER_S = 2.75e6, 0.9e6  # the paper's: 2.75 MB/s peak, 1 KiB at 0.9 MB/s
SECONDS_PER_RAY = 11522.0 / 1397473.0  # the paper's Teapot: T_1 over its rays (kIpsc2SecondsPerRay)


def network(**changed):
    """The preset's figures, with `changed` replacing some; the start-up
    (latency_s) is the paper's less the sender's overhead, whatever it is."""
    so = changed.get("send_overhead_s", SEND_OVERHEAD_S)
    figures = {"latency_s": 1024 / RATE_1K_B_PER_S - 1024 / PEAK_B_PER_S - so, "per_byte_s": 1 / PEAK_B_PER_S,
               "per_hop_s": 10e-6, "service_s": 100e-6, "fault_s": 100e-6, "send_overhead_s": so,
               "seconds_per_ray": SECONDS_PER_RAY, "contention": True}
    figures.update(changed)
    return figures


def main(argv):
    if len(argv) < 2:
        sys.exit(__doc__)
    changed = {}
    for arg in argv[2:]:
        key, sep, value = arg.partition("=")
        if not sep:
            sys.exit(f"ipsc2_machine.py: '{arg}' is not FIGURE=VALUE")
        changed[key] = value == "true" if value in ("true", "false") else float(value)
    print(json.dumps({"name": argv[1], "node_memory": "4MiB", "page_size": 1024, "topology": "hypercube",
                      "clock": "model", "network": network(**changed)}))


if __name__ == "__main__":
    main(sys.argv)
