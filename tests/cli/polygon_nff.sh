#!/usr/bin/env bash
# Writes one long NFF polygon to stdout (CLI cases of huge polygons).
#   polygon_nff.sh star N     N vertices alternating between radius 1 and 0.5 (concave)
#   polygon_nff.sh square M   a square of side M with M vertices per side (convex,
#                             integer coordinates, collinear runs)
set -euo pipefail
case $1 in
  star) awk -v n="$2" 'BEGIN { print "p", n; for (i = 0; i < n; ++i) { a = 6.283185307179586 * i / n; r = i % 2 ? 0.5 : 1; printf "%.9g %.9g 0\n", r * cos(a), r * sin(a) } }' ;;
  square) awk -v m="$2" 'BEGIN { print "p", 4 * m; for (i = 0; i < m; ++i) print i, 0, 0; for (i = 0; i < m; ++i) print m, i, 0; for (i = 0; i < m; ++i) print m - i, m, 0; for (i = 0; i < m; ++i) print 0, m - i, 0 }' ;;
  *) echo "polygon_nff.sh: star N or square M" >&2; exit 2 ;;
esac
