"""Writes an NFF file with its shapes in random order, for the svm layout
measurements (docs/primitive_order.sh): a scanned or exported mesh may list
its triangles in any order, and the shared virtual memory's file-order
layout then scatters a cell's triangles over many pages.

    python3 docs/shuffle_nff.py IN.nff OUT.nff [SEED]

Shapes (`p`, `pp`, `s`, `c` with their lines) are shuffled within each run
between other lines (`f`, `l`, `v` blocks ...), so every shape keeps its
material. IN may be gzipped (.gz).
"""
import gzip
import random
import sys


def read_lines(path):
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt") as f:
        return [line.rstrip("\n") for line in f]


def shape_length(words):
    """Lines a shape takes, its own included, or 0 for a line that is not a shape."""
    if not words:
        return 0
    if words[0] in ("p", "pp"):
        return 1 + int(words[1])
    if words[0] == "s":
        return 1
    if words[0] == "c":
        return 3
    return 0


def main(argv):
    if len(argv) not in (3, 4):
        print("usage: shuffle_nff.py IN.nff OUT.nff [SEED]", file=sys.stderr)
        return 2
    lines = read_lines(argv[1])
    rng = random.Random(int(argv[3]) if len(argv) == 4 else 1)
    out, run, i = [], [], 0
    while i < len(lines):
        n = shape_length(lines[i].split())
        if n == 0:
            rng.shuffle(run)
            out += [line for shape in run for line in shape]
            run = []
            out.append(lines[i])
            i += 1
            continue
        run.append(lines[i:i + n])
        i += n
    rng.shuffle(run)
    out += [line for shape in run for line in shape]
    with open(argv[2], "w") as f:
        f.write("\n".join(out) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
