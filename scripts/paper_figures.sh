#!/usr/bin/env bash
# The paper's nonlinear results (Figs. 10, 12, 13, 14 analogues): builds iem if needed, runs
# the three nonlinear scenes of inputs/ on 2 ranks into run/paper/, and writes the four
# figures into docs/img/ (or the folder given as the first argument), printing the numbers
# that docs/nonlinear.md quotes. The static cantilever also runs on a grid twice as fine
# (160 x 16) to show the convergence towards the fibre-section reference. About 3 minutes on
# 2 cores.
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
install_packages
make_venv
build_iem -DIEM_BUILD_TESTS=OFF
out="${1:-$IEM_ROOT/docs/img}"
mkdir -p "$IEM_ROOT/run/paper"
cd "$IEM_ROOT/run/paper"
n=$(demo_ranks)
for scene in cantilever_nonlinear_static simply_supported_nonlinear_static \
             cantilever_nonlinear_dynamic; do
  say "running $scene on $n ranks"
  mpirun -np "$n" "$IEM_BUILD/iem" "$IEM_ROOT/inputs/$scene.nml" > "$scene.log"
  grep -E "^(done|performance)" "$scene.log" || true
done
say "running cantilever_nonlinear_static on 160 x 16 on $n ranks"
sed -e "s/nx = 80, ny = 8/nx = 160, ny = 16/" \
    -e "s/cantilever_nonlinear_static.h5/cantilever_nonlinear_static_fine.h5/" \
    "$IEM_ROOT/inputs/cantilever_nonlinear_static.nml" > cantilever_nonlinear_static_fine.nml
mpirun -np "$n" "$IEM_BUILD/iem" cantilever_nonlinear_static_fine.nml \
  > cantilever_nonlinear_static_fine.log
grep -E "^done" cantilever_nonlinear_static_fine.log || true
say "plotting into $out"
"$IEM_VENV/bin/python" "$IEM_ROOT/postproc/scripts/paper_figures.py" --dir . --out "$out"
