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
#   --check CMD      shell command run in WORKDIR afterwards that must succeed
#                    (e.g. a file's content, a symlink kept); repeatable
#   --signal SIG@S   send signal SIG (TERM, INT, ...) to raynode S seconds
#                    after its start (it runs as a job of its own, so that
#                    SIGINT is not ignored as in a background job)
#   --env VAR=VALUE  run raynode with this environment variable; repeatable
#   --left FILE      a failing case may leave FILE (and must): what an
#                    interrupted command keeps, e.g. a sweep's CSV
#   --max-seconds S  raynode must end within S wall seconds (hard limits:
#                    --timeout plus its grace)
#
# For a failing case (EXPECT_RC != 0) the work directory must hold exactly the
# files it held before the run: no image, no --stats JSON, no AOV, no
# temporary file. STDERR_REGEX is an extended regular expression (grep -E).
set -uo pipefail

raynode=$(realpath "$1") workdir=$2 expect_rc=$3 regex=$4
shift 4
setup=() present=() stdout_re=() no_stdout_re=() checks=() envs=() left=() max_lines=2 limit=60 signal="" max_seconds=""
while [ $# -gt 0 ] && [ "$1" != "--" ]; do
  case $1 in
    --setup) setup+=("$2"); shift 2 ;;
    --present) present+=("$2"); shift 2 ;;
    --max-lines) max_lines=$2; shift 2 ;;
    --limit) limit=$2; shift 2 ;;
    --stdout) stdout_re+=("$2"); shift 2 ;;
    --no-stdout) no_stdout_re+=("$2"); shift 2 ;;
    --check) checks+=("$2"); shift 2 ;;
    --env) envs+=("$2"); shift 2 ;;
    --left) left+=("$2"); shift 2 ;;
    --signal) signal=$2; shift 2 ;;
    --max-seconds) max_seconds=$2; shift 2 ;;
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

start_ns=$(date +%s%N)
if [ -n "$signal" ]; then
  set -m  # job control: the job gets its own process group and keeps SIGINT
  env "${envs[@]}" timeout --kill-after=5 "$limit" "$raynode" "$@" >stdout.txt 2>stderr.txt </dev/null &
  job=$!
  sleep "${signal#*@}"
  # The signal goes to raynode, the child of timeout(1).
  pkill -"${signal%@*}" -P "$job" -x "$(basename "$raynode")"
  wait "$job"
  rc=$?
  set +m
else
  env "${envs[@]}" timeout --kill-after=5 "$limit" "$raynode" "$@" >stdout.txt 2>stderr.txt </dev/null
  rc=$?
fi
elapsed_ms=$(( ($(date +%s%N) - start_ns) / 1000000 ))
after=$(find . -mindepth 1 ! -name stdout.txt ! -name stderr.txt | LC_ALL=C sort)
for f in "${left[@]}"; do
  after=$(echo "$after" | grep -vxF "./$f")
done

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
if [ -n "$max_seconds" ] && [ "$elapsed_ms" -gt $(( max_seconds * 1000 )) ]; then
  say "raynode took ${elapsed_ms} ms, more than the ${max_seconds} s allowed"
fi
for c in "${checks[@]}"; do
  bash -c "$c" || say "check failed: $c"
done
for f in "${left[@]}"; do
  [ -s "$f" ] || say "'$f' should have been kept, but is missing or empty"
done
for f in "${present[@]}"; do
  [ -s "$f" ] || say "expected output '$f' is missing or empty"
done
[ "$fail" = 0 ] && echo "PASS"
exit "$fail"
