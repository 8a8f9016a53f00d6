#!/bin/bash
# A/B of grid walk and build between raynode builds on a machine of at
# least eight physical cores, one pinned benchmark per core (on a small
# machine, docs/ab_pair.sh runs one benchmark at a time; docs/results.md's
# "The grid against Embree" quotes such a run over this corpus):
#
#   docs/ab_accel.sh DIR OUT.txt
#
# DIR holds the builds as raynode_NAME and the scene files the builds read
# (tree_11.nff.gz, sombrero_1.nff.gz, gears_4.nff.gz, lattice_12.nff.gz,
# shells_5.nff.gz: `raynode scene write NAME:SIZE -o FILE`; scan_room.nff.gz:
# a 39,200-triangle displaced sphere on a floor beside a mirror wall,
# `python3 docs/scan_room.py scan_room.nff.gz`;
# teapot8_floor1000.nff.gz, tetra8_floor1000.nff.gz: `raynode scene write
# teapot:8` (or tetra:8) with one square floor polygon appended just below
# the model, 1000x its width: `p 4` at z = -0.01 for the teapot, -1.01 for
# Tetra, half-widths 4000 and 1000). One job per physical core (its first hardware thread), eight
# at once, two scenes per job, five alternated rounds of `bench accel SCENE
# --repeat 3 --width 256 --height 256 --json` ($REPEAT and $WIDTH, if set,
# replace the 3 and the 256 x 256); each line of OUT is
# NAME|ROUND|SCENE|JSON. A build named `old` skips the 1000x-floor scenes
# (a uniform grid takes minutes there). $LAUNCH, if set, prefixes each run
# (e.g. a dynamic loader and --library-path for builds carried elsewhere).
set -u
dir=$(realpath "${1:?DIR}"); out=$(realpath -m "${2:?OUT.txt}")
cd "$dir"
bins=$(ls raynode_* | sed 's/raynode_//')
cores=$(cat /sys/devices/system/cpu/cpu*/topology/thread_siblings_list | sed 's/[,-].*//' | sort -un | head -8)
echo "cores: $cores; builds: $bins"
rm -f "$out".core*
job() {
  core=$1; shift
  for rep in 1 2 3 4 5; do
    for spec in "$@"; do
      for b in $bins; do
        case "$b|$spec" in old\|*floor1000*) continue ;; esac
        r=$(timeout 60 taskset -c "$core" ${LAUNCH:-} "./raynode_$b" bench accel $spec --repeat "${REPEAT:-3}" \
            --width "${WIDTH:-256}" --height "${WIDTH:-256}" --json 2>/dev/null | tr -d '\n ')
        echo "$b|$rep|$spec|$r" >> "$out.core$core"
      done
    done
  done
}
set -- $cores
job "$1" "teapot:8" "tree_11.nff.gz" &
job "$2" "mount:6 -t 6" "balls:4" &
job "$3" "rings:4 -t 1" "mount:6" &
job "$4" "tetra:9" "sombrero_1.nff.gz" &
job "$5" "scan_room.nff.gz" "rings:4" &
job "$6" "gears_4.nff.gz" "tetra8_floor1000.nff.gz" &
job "$7" "lattice_12.nff.gz" "balls:4 -t 1" &
job "$8" "shells_5.nff.gz" "teapot8_floor1000.nff.gz" &
wait
cat "$out".core* > "$out" && rm -f "$out".core*
wc -l "$out"
