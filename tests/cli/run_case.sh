#!/usr/bin/env bash
# One CLI robustness case: runs the raynode program in a fresh work directory
# and checks its exit status, its message on stderr, and the files it left.
#
#   run_case.sh RAYNODE WORKDIR EXPECT_RC STDERR_REGEX [options] -- ARGS...
#
# options:
#   --setup CMD      shell command run in WORKDIR before the case (makes inputs)
#   --present FILE   FILE must exist afterwards (success cases)
#   --max-lines N    stderr has at most N lines (default 2: one message, plus
#                    CLI11's "Run 'raynode --help'" hint for exit status 2)
#   --limit S        seconds before the case counts as hung (default 60)
#   --stdout REGEX   a line of stdout must match REGEX (grep -E); repeatable
#   --no-stdout REGEX  no line of stdout may match REGEX; repeatable
#
# For a failing case (EXPECT_RC != 0) the work directory must hold exactly the
# files it held before the run: no image, no --stats JSON, no AOV, no
# temporary file. STDERR_REGEX is an extended regular expression (grep -E).
set -uo pipefail

raynode=$(realpath "$1") workdir=$2 expect_rc=$3 regex=$4
shift 4
setup=() present=() stdout_re=() no_stdout_re=() max_lines=2 limit=60
while [ $# -gt 0 ] && [ "$1" != "--" ]; do
  case $1 in
    --setup) setup+=("$2"); shift 2 ;;
    --present) present+=("$2"); shift 2 ;;
    --max-lines) max_lines=$2; shift 2 ;;
    --limit) limit=$2; shift 2 ;;
    --stdout) stdout_re+=("$2"); shift 2 ;;
    --no-stdout) no_stdout_re+=("$2"); shift 2 ;;
    *) echo "run_case.sh: unknown option '$1'" >&2; exit 2 ;;
  esac
done
[ "${1:-}" = "--" ] || { echo "run_case.sh: missing -- before the raynode arguments" >&2; exit 2; }
shift

rm -rf "$workdir" && mkdir -p "$workdir" && cd "$workdir" || exit 2
for cmd in "${setup[@]}"; do
  bash -c "$cmd" || { echo "FAIL: setup command failed: $cmd"; exit 1; }
done
before=$(find . -mindepth 1 | LC_ALL=C sort)

timeout --kill-after=5 "$limit" "$raynode" "$@" >stdout.txt 2>stderr.txt </dev/null
rc=$?
after=$(find . -mindepth 1 ! -name stdout.txt ! -name stderr.txt | LC_ALL=C sort)

fail=0
say() { echo "FAIL: $*"; fail=1; }
echo "command: raynode $*"
echo "exit status: $rc (expected $expect_rc)"
echo "stderr:"; sed 's/^/  | /' stderr.txt
if [ "$rc" = 124 ] || [ "$rc" = 137 ]; then say "raynode did not finish within $limit s (hang)"; fi
[ "$rc" = "$expect_rc" ] || say "exit status $rc, expected $expect_rc"
if [ -n "$regex" ] && ! grep -Eq -- "$regex" stderr.txt; then say "stderr does not match /$regex/"; fi
lines=$(wc -l <stderr.txt)
[ "$lines" -le "$max_lines" ] || say "stderr has $lines lines, at most $max_lines expected (one clear message)"
if [ "$expect_rc" != 0 ]; then
  [ -s stderr.txt ] || say "no message on stderr"
  if [ "$before" != "$after" ]; then
    say "the failed run left files behind:"
    comm -13 <(echo "$before") <(echo "$after") | sed 's/^/  + /'
  fi
fi
for re in "${stdout_re[@]}"; do
  grep -Eq -- "$re" stdout.txt || { say "no line of stdout matches /$re/; stdout:"; sed 's/^/  | /' stdout.txt; }
done
for re in "${no_stdout_re[@]}"; do
  ! grep -Eq -- "$re" stdout.txt || { say "a line of stdout matches /$re/, which none should; stdout:"; sed 's/^/  | /' stdout.txt; }
done
for f in "${present[@]}"; do
  [ -s "$f" ] || say "expected output '$f' is missing or empty"
done
[ "$fail" = 0 ] && echo "PASS"
exit "$fail"
