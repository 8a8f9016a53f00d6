#!/usr/bin/env bash
# --floor K (core::add_stadium_floor): a scene on a square floor K times its
# width. The option and a file written with it render the same bytes, in
# sequential and svm mode alike; render's stats record K; validate finds
# the grid and Embree in agreement on the floored scene (the adaptive grid
# sets both the scene's own ground and the stadium floor beside its top
# grid); a K below 1 is refused with exit 2.
#
#   stadium_floor.sh RAYNODE WORKDIR
set -uo pipefail
raynode=$(realpath "$1") workdir=$2
# shellcheck source=tests/cli/render_lib.sh
. "$(dirname "$0")/render_lib.sh"

"$raynode" scene write balls:2 -t 1 --floor 100 -o floored.nff || { echo "FAIL: scene write --floor"; exit 1; }
render plain.ppm balls:2 -t 1
render option.ppm balls:2 -t 1 --floor 100 --stats option.json
render file.ppm floored.nff
render svm.ppm balls:2 -t 1 --floor 100 --mode svm --nodes 3
if cmp -s option.ppm file.ppm && cmp -s option.ppm svm.ppm; then
  echo "ok: --floor 100, the file written with it and svm render the same image"
else
  echo "FAIL: --floor 100, its file and svm differ"; fail=1
fi
if cmp -s plain.ppm option.ppm; then echo "FAIL: the floor changed nothing in the image"; fail=1; fi
if python3 -c "import json,sys; sys.exit(json.load(open('option.json'))['floor'] != 100)"; then
  echo "ok: the stats record floor 100"
else
  echo "FAIL: the stats do not record floor 100"; fail=1
fi
if timeout 100 "$raynode" validate balls:2 -t 1 --floor 1000 --width 48 --height 48 > validate.txt 2>&1 &&
    grep -q "zero mismatches" validate.txt; then
  echo "ok: validate, zero mismatches on a 1000x floor"
else
  echo "FAIL: validate --floor 1000:"; cat validate.txt; fail=1
fi
"$raynode" render balls:2 --floor 0.5 -o bad.ppm > bad.out 2> bad.err
status=$?
if [ "$status" -eq 2 ] && [ "$(wc -l < bad.err)" -le 2 ] && grep -q -- "--floor" bad.err && [ ! -e bad.ppm ]; then
  echo "ok: --floor 0.5 refused (exit 2, no output)"
else
  echo "FAIL: --floor 0.5 gave exit $status:"; cat bad.err; fail=1
fi
exit $fail
