#!/bin/bash
# The grid against Embree on meshes raynode was never tuned on: the meshes
# of Debian's libcgal-demo package (CGAL's data set: scans such as the
# Stanford bunny and armadillo, and modelled meshes), alone and as stadium
# variants, as quoted in docs/results.md ("Meshes from Debian's CGAL data"):
#
#   docs/scanned_meshes.sh RAYNODE DIR OUT.csv ROUNDS [MESH...]
#
# DIR receives the meshes: if DIR/meshes does not hold them yet, the package
# is fetched with `apt-get download libcgal-demo` (network needed, no root)
# and the meshes are taken out of its data.tar.gz. MESH names files of
# CGAL's data/meshes (default: the list below). For each mesh and floor
# (none, --floor 100, --floor 1000), ROUNDS alternated rounds of
# `bench accel MESH [--floor K] --repeat 3 --width 256 --height 256 --json`,
# then one `validate MESH [--floor K] --json` (its defaults: 512x512 primary
# rays, 400,000 random rays and their secondaries) and svm renders on 8
# nodes, `render MESH [--floor K] --mode svm --nodes 8 --grid adaptive
# --width 128 --height 128 --stats FILE`, for svm's pages per pixel, and the
# same with --grid uniform for the mesh alone (on a floor the uniform grid
# takes minutes a render: its few, huge cells); and, for the mesh alone, svm's
# efficiency at 64 nodes on the emulated iPSC/2 with either grid, `bench
# nodes MESH --mode svm --network ipsc2 --clock model --grid adaptive|uniform
# --node-memory 16MiB --nodes 1,64 --repeat 3 --width 512 --height 512`: the
# best of three, as virtual times at 64 nodes vary by a few points from run
# to run with the order in which nodes steal work items). OUT.csv
# gets a row per mesh, floor and round: the bench figures, then the
# validate mismatches, the two pages per pixel and the two efficiencies (the
# same on every round). With SVM=off in the environment the svm renders and
# bench nodes are skipped, and their columns stay empty.
set -u
here=$(dirname "$(realpath "$0")")  # corpus_csv.py beside this script
bin=$(realpath "${1:?RAYNODE}"); dir=$(realpath -m "${2:?DIR}"); out=$(realpath -m "${3:?OUT.csv}")
rounds=${4:?ROUNDS}
shift 4
meshes=("$@")
if [ ${#meshes[@]} -eq 0 ]; then
  meshes=(bunny00.off armadillo.off ChineseDragon-10kv.off refined_elephant.off femur.off lion.off pig.stl
          camel.off bear.off man.off homer.off dino.off cow.off diplodocus.off mannequin-devil.off)
fi
mkdir -p "$dir/meshes"
missing=0
for m in "${meshes[@]}"; do [ -s "$dir/meshes/$m" ] || missing=1; done
if [ $missing = 1 ]; then
  (cd "$dir" && rm -f libcgal-demo_*.deb && apt-get download libcgal-demo) || { echo "cannot fetch libcgal-demo"; exit 1; }
  deb=$(find "$dir" -maxdepth 1 -name "libcgal-demo_*.deb" | head -1)
  rm -rf "$dir/pkg" && dpkg-deb -x "$deb" "$dir/pkg"
  members=()
  for m in "${meshes[@]}"; do members+=("data/meshes/$m"); done
  tar xzf "$dir/pkg/usr/share/doc/libcgal-dev/data.tar.gz" -C "$dir" "${members[@]}" || exit 1
  for m in "${meshes[@]}"; do mv "$dir/data/meshes/$m" "$dir/meshes/$m"; done
  rm -rf "$dir/pkg" "$dir/data"
fi
raw=$(mktemp); tmp=$(mktemp -d); trap 'rm -rf "$raw" "$tmp"' EXIT
cd "$dir/meshes" || exit 1
floors=("" "--floor 100" "--floor 1000")
for round in $(seq 1 "$rounds"); do
  for m in "${meshes[@]}"; do
    for f in "${floors[@]}"; do
      # $f is split on purpose: a flag and its value.
      # shellcheck disable=SC2086
      j=$("$bin" bench accel "$m" $f --repeat 3 --width 256 --height 256 --json 2>/dev/null | tr -d '\n ')
      echo "bench|$round|$m|${f#--floor }|$j" >> "$raw"
    done
  done
done
for m in "${meshes[@]}"; do
  for f in "${floors[@]}"; do
    # shellcheck disable=SC2086
    j=$("$bin" validate "$m" $f --json 2>/dev/null | tr -d '\n ')
    echo "validate|0|$m|${f#--floor }|$j" >> "$raw"
    [ "${SVM:-on}" = off ] && continue
    grids=(adaptive)
    [ -z "$f" ] && grids+=(uniform)  # the uniform grid on a floor: minutes a render, as the issue's stadiums
    for g in "${grids[@]}"; do
      # shellcheck disable=SC2086
      "$bin" render "$m" $f --mode svm --nodes 8 --grid $g --width 128 --height 128 -o "$tmp/img.png" \
        --stats "$tmp/s.json" >/dev/null 2>&1
      echo "svm_$g|0|$m|${f#--floor }|$(tr -d '\n ' < "$tmp/s.json")" >> "$raw"
      rm -f "$tmp/s.json"
    done
  done
  [ "${SVM:-on}" = off ] && continue
  for g in adaptive uniform; do
    "$bin" bench nodes "$m" --mode svm --network ipsc2 --clock model --grid $g --node-memory 16MiB --nodes 1,64 --repeat 3 \
      --width 512 --height 512 --json "$tmp/n.json" >/dev/null 2>&1
    echo "nodes_$g|0|$m|0|$(tr -d '\n ' < "$tmp/n.json")" >> "$raw"
    rm -f "$tmp/n.json"
  done
done
python3 "$here/corpus_csv.py" "$raw" "$out"
wc -l "$out"
