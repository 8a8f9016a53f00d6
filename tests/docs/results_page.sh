#!/usr/bin/env bash
# docs/results.md is exactly what docs/make_results.py writes from the data
# under docs/results/ (every number on the page is read from a file a quoted
# command wrote), and the check does catch a page whose numbers were edited.
#
#   results_page.sh PYTHON SOURCE_DIR WORKDIR
set -uo pipefail
python=$1 src=$2 work=$3
rm -rf "$work" && mkdir -p "$work" || exit 2
fail=0
"$python" "$src/docs/make_results.py" --check || { echo "FAIL: docs/results.md is not what its data give"; fail=1; }
# A page with one table number changed must be refused.
awk 'done == 0 && /^\| .*[0-9]\.[0-9]/ { sub(/[0-9]\.[0-9]/, "9.9"); done = 1 } { print }' \
  "$src/docs/results.md" > "$work/edited.md"
if cmp -s "$src/docs/results.md" "$work/edited.md"; then
  echo "FAIL: no table number found to edit"; fail=1
elif "$python" "$src/docs/make_results.py" --check "$work/edited.md" 2>"$work/err"; then
  echo "FAIL: an edited number passed the check"; fail=1
else
  grep -q "edited.md:[0-9]*: differs" "$work/err" || { echo "FAIL: the check did not name the line:"; cat "$work/err"; fail=1; }
fi
exit $fail
