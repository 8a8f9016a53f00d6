# Shared by the CLI scripts that render small images and compare them
# (moved_scene.sh, stadium_floor.sh); sourced after they set `raynode` (the
# program's absolute path) and `workdir`. Makes WORKDIR afresh and enters
# it, sets fail=0, and defines render OUT SCENE ARGS...: a 48x48 render to
# OUT that, on failure, prints its stderr and sets fail=1.
rm -rf "$workdir" && mkdir -p "$workdir" && cd "$workdir" || exit 2

fail=0
render() {  # render OUT SCENE ARGS...
  local out=$1; shift
  if ! timeout --kill-after=5 100 "$raynode" render "$@" --width 48 --height 48 --quiet --timeout 60 -o "$out" \
      2> "$out.err"; then
    echo "FAIL: render $* :"; cat "$out.err"; fail=1
  fi
}
