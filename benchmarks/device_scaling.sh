#!/usr/bin/env bash
# Issue 12's scaling and speed figures on a lent many-core machine, in one call of at most
# 9 minutes (give the call timeout_s 590): run from the repository root there, after
# benchmarks/device_prepare.sh here, carrying .devrun (docs/benchmarks.md, "Scaling").
# Needs python3 with h5py and numpy, and Open MPI's mpirun. Each section has a time limit
# inside a budget (BUDGET seconds, default 540); what a section prints goes to
# $OUT/tables.md (its standard error to $OUT/err.txt), everything to $OUT/log.txt, and
# speed.py's runs to $OUT/speed.json. Sections, in order:
#   machine   processor, cores, memory, MPI; which build runs (native where the processor
#             has every feature in .devrun/native/flags, else x86-64-v3)
#   ceiling   the machine's own limit for many ranks: independent 1-rank runs of the block of
#             1e6/N nodes at once, one pinned to each core, against one run alone (so that
#             strong scaling can be read against what the cores reach with no messages)
#   strong_rk4_1..3, weak_rk4 (1e5 nodes a rank): benchmarks/throughput.py on 1 2 4 8 16
#             ranks (those of them the processors allow)
#   speed     benchmarks/speed.py --repeat 3, new against the baseline: size, force, rk4,
#             verlet, memory, weak (about 200 s on the 16-core machine lent on 2026-12-04)
#   strong_verlet (3 times), weak2_rk4 (5e5 nodes a rank, 1 and 2 ranks, 3 times)
# SCALE (default 1) scales the work of each run, for a dry run on a small machine.
set -u
PY=${PY:-python3}
OUT=${OUT:-/tmp/device-scaling}; mkdir -p "$OUT"
D=$PWD/.devrun
SCALE=${SCALE:-1}
T0=$(date +%s)
left() { echo $(( ${BUDGET:-540} - ($(date +%s) - T0) )); }
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 PYTHONUNBUFFERED=1
export LD_LIBRARY_PATH=$D/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
[ -x "$D/v3/new/iem" ] ||
  { echo "no $D/v3/new/iem: run benchmarks/device_prepare.sh first" >&2; exit 2; }
exec > >(tee -a "$OUT/log.txt") 2>&1

echo "== machine"; date -u; uname -r; nproc; lscpu | sed -n '1,30p'; free -g | head -2
cat "$D/BUILT" 2>/dev/null
mpirun --version 2>&1 | head -1; $PY -c 'import h5py, numpy; print("h5py", h5py.__version__)'
flags=" $(grep -m1 '^flags' /proc/cpuinfo | cut -d: -f2) "
build=native
while read -r f; do
  [[ $flags == *" $f "* ]] || { build=v3; echo "no $f: the x86-64-v3 builds run"; break; }
done < "$D/native/flags"
for f in avx2 fma; do [[ $flags == *" $f "* ]] || { echo "no $f: nothing can run"; exit 3; }; done
NEW=$D/$build/new/iem; OLD=$D/$build/base/iem
NC=$(nproc)
tpc=$(lscpu | awk -F: '/Thread\(s\) per core/ {gsub(/ /, "", $2); print $2}')
cores=$(( NC / ${tpc:-1} ))
echo "build: $build; $NC processors, $cores cores"
# mpirun as throughput.py calls it (-n N --oversubscribe --bind-to core ...), binding to
# hardware threads beyond the cores and to nothing beyond the processors
cat > "$D/mpx" <<EOW
#!/usr/bin/env bash
n=1; a=("\$@"); for ((i = 0; i < \${#a[@]}; i++)); do [[ \${a[i]} == -n ]] && n=\${a[i+1]}; done
if (( n > $NC )); then exec mpirun \$MPX_EXTRA "\${a[@]/#core/none}"; fi
if (( n > $cores )); then exec mpirun --use-hwthread-cpus \$MPX_EXTRA "\${a[@]/#core/hwthread}"; fi
exec mpirun \$MPX_EXTRA "\${a[@]}"
EOW
chmod +x "$D/mpx"
ROOT=$PWD
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
cd "$W"
echo "== smoke"
$PY "$ROOT/benchmarks/throughput.py" --sizes 2e3 --work 1e5 --write-case s.nml > /dev/null
export MPX_EXTRA=""
if ! timeout 60 "$D/mpx" -n 2 --oversubscribe --bind-to core "$NEW" s.nml > s.log 2>&1; then
  tail -n 30 s.log
  export MPX_EXTRA="--mca pml ob1 --mca btl self,vader"
  echo "again with $MPX_EXTRA"
  timeout 60 "$D/mpx" -n 2 --oversubscribe --bind-to core "$NEW" s.nml > s.log 2>&1 ||
    { tail -n 40 s.log; exit 4; }
fi
grep -E "performance" s.log
timeout 60 "$D/mpx" -n 1 --oversubscribe --bind-to core "$OLD" s.nml > o.log 2>&1 ||
  { tail -n 30 o.log; exit 5; }

sec() { # NAME LIMIT COMMAND...: run a section if time is left, within LIMIT seconds
  local name=$1 lim=$2; shift 2; local l; l=$(left)
  (( l < 20 )) && { echo "== $name: skipped (${l} s left)"; return; }
  (( lim > l - 10 )) && lim=$(( l - 10 ))
  echo "== $name (limit ${lim} s, $(( $(date +%s) - T0 )) s in)"
  timeout --signal=INT "$lim" "$@" > "$OUT/section.tmp" 2> "$OUT/err.tmp"
  echo "exit status $?"; cat "$OUT/section.tmp"; tail -n 3 "$OUT/err.tmp"
  { echo "## $name"; cat "$OUT/section.tmp"; } >> "$OUT/tables.md"
  { echo "## $name"; cat "$OUT/err.tmp"; } >> "$OUT/err.txt"
  rm -f "$OUT/section.tmp" "$OUT/err.tmp"
}
rate() { grep -h "performance:" "$@" | sed 's/.*s: *\([0-9.E+-]*\) node-steps.*/\1/'; }
one() { # CORE DIR: one 1-rank run of ceil.nml pinned to CORE, in DIR
  mkdir -p "$2"
  # (each its own TMPDIR: mpiruns started together race on a shared Open MPI session folder)
  (cd "$2" && TMPDIR=$PWD taskset -c "$1" mpirun $MPX_EXTRA -n 1 --bind-to none "$NEW" \
    "$W/ceil.nml" > o.log 2>&1)
}
many() { # LABEL CORE...: one run on each core at once; the median, min and max rate
  local label=$1; shift; rm -rf m; local pids=()
  for c in "$@"; do one "$c" "m/$c" & pids+=($!); done
  wait "${pids[@]}"
  echo "| $label | $# | $(rate m/*/o.log | $PY -c 'import sys, statistics as s
x = [float(v) for v in sys.stdin]
print("%.3e | %.3e | %.3e" % (s.median(x), min(x), max(x)) if x else "failed | |")') |"
}
ceiling() { # the runs of the ceiling section
  echo "| runs at once | runs | node-steps/s each: median | min | max |"
  echo "|---|---|---|---|---|"
  for rep in 1 2; do
    many "alone (core 0)" 0
    many "alone (core $((NC - 1)))" $((NC - 1))
    many "all $NC cores" $(seq 0 $((NC - 1)))
    many "$((NC / 2)) (cores 0-$((NC / 2 - 1)))" $(seq 0 $((NC / 2 - 1)))
    many "$((NC / 2)) (even cores)" $(seq 0 2 $((NC - 1)))
    many "2 (cores 0, 1)" 0 1
  done
  awk '/^cpu / {print "steal time so far (jiffies, all processors): " $9}' /proc/stat
}
$PY "$ROOT/benchmarks/throughput.py" --sizes "$(( 1000000 / NC ))" \
  --work "$($PY -c "print(3e7 * $SCALE)")" --write-case ceil.nml
cd "$ROOT"
export MPX_EXTRA NEW W NC PY
export -f rate one many ceiling
TP="$PY benchmarks/throughput.py --iem $NEW --mpiexec $D/mpx"
RANKS=$(for r in 1 2 4 8 16 32 64; do (( r <= NC )) && echo -n "$r "; done)
work() { $PY -c "print($1 * $SCALE)"; }
sec ceiling 90 bash -c "cd $W && ceiling"
for rep in 1 2 3; do
  sec strong_rk4_$rep 150 $TP --ranks $RANKS --sizes 1e6 --work "$(work 2e8)"
done
sec weak_rk4 150 $TP --ranks $RANKS --sizes 1e5 --weak --work "$(work 1e8)"
sec speed 240 $PY benchmarks/speed.py --iem "$NEW" --baseline "$OLD" --repeat 3 --mpiexec "$D/mpx" \
  --only size,force,rk4,verlet,memory,weak --save "$OUT/speed.json" ${SPEED_ARGS:-}
sec strong_verlet 90 bash -c \
  "for i in 1 2 3; do $TP --ranks $RANKS --sizes 1e6 --work $(work 4e8) --integrator verlet; done"
sec weak2_rk4 120 bash -c \
  "for i in 1 2 3; do $TP --ranks 1 2 --sizes 5e5 --weak --work $(work 1e8); done"
echo "== done in $(( $(date +%s) - T0 )) s"
