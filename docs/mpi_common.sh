# shellcheck shell=bash
# Sourced by the docs/mpi_*.sh measuring scripts: what every one of them
# sets up before its first mpirun.
#   - Open MPI may run as root (CI's containers) and place more ranks than
#     cores (a 2-core machine measuring 4 ranks);
#   - $work: a scratch folder, removed on exit;
#   - json_value FILE KEY...: a value of a --stats or bench JSON file, by its keys
#     (e.g. json_value s.json machine wall_s).
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
json_value() {
  python3 -c "
import json, sys
v = json.load(open(sys.argv[1]))
for k in sys.argv[2:]:
    v = v[int(k)] if isinstance(v, list) else v[k]
print(v)" "$@"
}
