#!/usr/bin/env bash
# A short side-by-side of the new build against the baseline on a lent many-core machine, in
# one call of about 3 minutes (give the call timeout_s 300): run from the repository root
# there, after benchmarks/device_prepare.sh [BASELINE_REV] here, carrying .devrun. For a
# change whose effect shows at many ranks, when too little device time is left for
# benchmarks/device_scaling.sh. Prints, in order (each section within its time limit):
#   rk4_16     RK4, 1e6 nodes, 16 ranks: new against old, 5 interleaved runs each
#   verlet_16  the same with velocity Verlet, 3 runs each
#   rk4_2      RK4, 2e5 nodes on 2 ranks (the 2-rank weak case's block), 5 runs each
#   strong     the new build's strong scaling of 1e6 nodes, RK4, on 1 2 4 8 16 ranks
#   weak       the new build's weak scaling, 1e5 nodes a rank, 1 and 16 ranks
#   balance_16 the new build, RK4, 1e6 nodes (392 steps), 16 ranks: load balancing every 50
#              steps (&run balance_interval) against none, 3 interleaved runs each
# Output goes to $OUT/log.txt too. Needs python3 and Open MPI's mpirun.
set -u
OUT=${OUT:-/tmp/device-compare}; mkdir -p "$OUT"
D=$PWD/.devrun
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 PYTHONUNBUFFERED=1
export LD_LIBRARY_PATH=$D/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
exec > >(tee -a "$OUT/log.txt") 2>&1
build=native
flags=" $(grep -m1 '^flags' /proc/cpuinfo | cut -d: -f2) "
while read -r f; do [[ $flags == *" $f "* ]] || { build=v3; break; }; done < "$D/native/flags"
NEW=$D/$build/new/iem; OLD=$D/$build/base/iem
echo "build $build; $(nproc) processors; $(cat "$D/BUILT" | tr '\n' ' ')"
T0=$(date +%s)
sec() { # NAME LIMIT ARGS...: throughput.py ARGS within LIMIT seconds
  local name=$1 lim=$2; shift 2
  echo "== $name ($(( $(date +%s) - T0 )) s in)"
  timeout --signal=INT "$lim" python3 benchmarks/throughput.py --iem "$NEW" "$@" 2>&1 |
    grep -v '^# [0-9]*/[0-9]* '
}
sec rk4_16 60 --baseline "$OLD" --ranks 16 --sizes 1e6 --work 2e8 --repeat 5
sec verlet_16 40 --baseline "$OLD" --ranks 16 --sizes 1e6 --work 4e8 --repeat 3 \
  --integrator verlet
sec rk4_2 45 --baseline "$OLD" --ranks 2 --sizes 2e5 --work 1e8 --repeat 5
sec strong 45 --ranks 1 2 4 8 16 --sizes 1e6 --work 2e8
sec weak 25 --ranks 1 16 --sizes 1e5 --weak --work 1e8
W=$(mktemp -d)
python3 benchmarks/throughput.py --sizes 1e6 --work 8e8 --write-case "$W/plain.nml" > /dev/null
sed "s/  integrator = 'rk4'/  integrator = 'rk4', balance_interval = 50/" "$W/plain.nml" \
  > "$W/balanced.nml"
sec balance_16 60 --input "$W/plain.nml" --input "$W/balanced.nml" --ranks 16 --repeat 3
rm -rf "$W"
echo "== done in $(( $(date +%s) - T0 )) s"
