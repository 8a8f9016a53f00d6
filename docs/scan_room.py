"""A scan-like mesh in a room, for the grid benchmark corpus (docs/ab_accel.sh).

A displaced sphere of 140 x 140 x 2 = 39,200 small triangles, its bumps of
several frequencies, standing on a floor polygon beside a mirror wall, with
two lights, written as gzipped NFF:

    python3 docs/scan_room.py scan_room.nff.gz
"""
import math, sys, gzip
n = 140
def r(th, ph):
    return 1.0 + 0.08*math.sin(7*th)*math.cos(5*ph) + 0.04*math.sin(19*th + 3*ph) + 0.02*math.cos(31*ph - 11*th)
pts = []
for i in range(n + 1):
    th = math.pi * i / n
    row = []
    for j in range(n):
        ph = 2*math.pi*j/n
        rr = r(th, ph)
        row.append((rr*math.sin(th)*math.cos(ph), rr*math.sin(th)*math.sin(ph), 1.1 + rr*math.cos(th)))
    pts.append(row)
out = []
out.append("v\nfrom 4 -5 2.5\nat 0 0 1\nup 0 0 1\nangle 40\nhither 0.01\nresolution 512 512")
out.append("b 0.1 0.1 0.2")
out.append("l 5 -5 8\nl -4 -6 6")
out.append("f 0.8 0.8 0.8 0.8 0.2 20 0 1")
out.append("p 4\n-6 -6 0\n6 -6 0\n6 6 0\n-6 6 0")
out.append("f 0.9 0.9 0.9 0.1 0.9 60 0 1")
out.append("p 4\n-6 3 0\n6 3 0\n6 3 5\n-6 3 5")
out.append("f 0.7 0.5 0.3 0.8 0.3 30 0 1")
fmt = lambda p: "%.6f %.6f %.6f" % p
for i in range(n):
    for j in range(n):
        a, b = pts[i][j], pts[i][(j+1) % n]
        c, d = pts[i+1][j], pts[i+1][(j+1) % n]
        out.append("p 3\n%s\n%s\n%s" % (fmt(a), fmt(c), fmt(d)))
        out.append("p 3\n%s\n%s\n%s" % (fmt(a), fmt(d), fmt(b)))
with gzip.open(sys.argv[1], "wt") as f:
    f.write("\n".join(out) + "\n")
