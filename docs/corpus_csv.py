"""The CSV of docs/scanned_meshes.sh and docs/spd_corpus.sh from their raw lines:

    python3 docs/corpus_csv.py RAW OUT.csv

Each line of RAW is KIND|ROUND|SCENE|FLOOR|JSON: KIND bench (a `bench accel --json` run), validate (a
`validate --json` run), svm_adaptive or svm_uniform (a render's --stats) or nodes_adaptive or nodes_uniform
(a `bench nodes --json` file). OUT gets a row per bench run, with the other kinds' figures for its scene and
floor (empty where a script did not run them).
"""
import csv, json, sys
bench, extra = [], {}
for line in open(sys.argv[1]):
    kind, rnd, mesh, floor, j = line.rstrip("\n").split("|", 4)
    floor = floor or "0"
    try:
        d = json.loads(j)
    except ValueError:
        continue  # a run that failed leaves no figure
    if kind == "bench":
        bench.append((rnd, mesh, floor, d[0]))
    elif kind == "validate":
        extra.setdefault((mesh, floor), {})["mismatches"] = d["mismatches"]
        extra[(mesh, floor)]["validate_rays"] = d["rays"]
    elif kind.startswith("nodes_"):
        rows = {r["nodes"]: r for r in d["rows"]}
        extra.setdefault((mesh, floor), {})[kind[6:] + "_efficiency_64"] = f"{rows[64]['efficiency']:.4f}"
    else:
        extra.setdefault((mesh, floor), {})[kind + "_pages_per_pixel"] = f"{d['svm']['pages_per_pixel']:.2f}"
keys = ["mismatches", "validate_rays", "svm_adaptive_pages_per_pixel", "svm_uniform_pages_per_pixel",
        "adaptive_efficiency_64", "uniform_efficiency_64"]
with open(sys.argv[2], "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(["mesh", "floor", "round", "primitives", "grid_over_embree_time", "grid_rays_per_s",
                "embree_rays_per_s", "tests_per_ray", "cells_per_ray", "grid_build_s", "embree_build_s",
                "grid_bytes", "embree_bytes"] + keys)
    for rnd, mesh, floor, d in bench:
        e = extra.get((mesh, floor), {})
        w.writerow([mesh, floor, rnd, d["primitives"], f"{d['grid_over_embree_time']:.4f}",
                    f"{d['grid_rays_per_s']:.0f}", f"{d['embree_rays_per_s']:.0f}", f"{d['tests_per_ray']:.2f}",
                    f"{d['cells_per_ray']:.2f}", f"{d['grid_build_s']:.6f}", f"{d['embree_build_s']:.6f}",
                    d["grid_bytes"], d["embree_bytes"]] + [e.get(k, "") for k in keys])
