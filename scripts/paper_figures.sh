#!/usr/bin/env bash
# The paper's nonlinear results (Figs. 10, 12, 13, 14 analogues): builds iem if needed, runs
# the three nonlinear scenes of inputs/ on 2 ranks into run/paper/, and writes the four
# figures into docs/img/ (or the folder given as the first argument), printing the numbers
# that docs/nonlinear.md quotes. The static cantilever also runs on a grid twice as fine
# (160 x 16) to show the convergence towards the fibre-section reference. Then the paper's
# concrete beams with fracture (Figs. 15-18): the cantilever and the simply supported beam of
# inputs/concrete_*_fracture.nml run into run/fracture/, their crack maps at three stages,
# their damage near the crack and their load-deflection curves go into the same folder, and
# postproc/scripts/concrete_beams.py prints the numbers docs/fracture.md quotes. About 3
# minutes on 2 cores for the nonlinear part, 1.5 more for the fracture part (6 when the cores
# are shared with other work); FRACTURE_ONLY=1 runs only the fracture part.
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
install_packages
make_venv
build_iem -DIEM_BUILD_TESTS=OFF
out="${1:-$IEM_ROOT/docs/img}"
mkdir -p "$out" && out=$(cd "$out" && pwd)
mkdir -p "$IEM_ROOT/run/paper"
cd "$IEM_ROOT/run/paper"
n=$(demo_ranks)
post() { PYTHONPATH="$IEM_ROOT/postproc" "$IEM_VENV/bin/python" -m iem_post "$@"; }
if [ -z "${FRACTURE_ONLY:-}" ]; then
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
fi

# The concrete beams with fracture (Figs. 15-18): crack maps at three stages (frames every
# 10 ms: cantilever 0.3, 0.45, 0.6 s; beam 0.12, 0.3, 0.8 s; the last one drawn deformed) and
# the load-deflection curves.
mkdir -p "$IEM_ROOT/run/fracture"
cd "$IEM_ROOT/run/fracture"
for scene in concrete_cantilever_fracture concrete_beam_fracture; do
  say "running $scene on $n ranks"
  mpirun -np "$n" "$IEM_BUILD/iem" "$IEM_ROOT/inputs/$scene.nml" > "$scene.log"
  grep -E "^(done|performance)" "$scene.log" || true
done
say "plotting the crack maps and load curves into $out"
for frame in 30 45; do
  post crack-map concrete_cantilever_fracture.h5 --frame "$frame" \
    -o "$out/fig17_cantilever_cracks_$frame.png"
done
post crack-map concrete_cantilever_fracture.h5 --frame 60 --scale auto \
  -o "$out/fig17_cantilever_cracks_60.png"
post curve concrete_cantilever_fracture.h5 --load tip:y --load-scale=-1 \
  --displacement tip:y --displacement-scale=-1e3 -o "$out/fig17_cantilever_curve.png"
for frame in 12 30; do
  post crack-map concrete_beam_fracture.h5 --frame "$frame" -o "$out/fig18_beam_cracks_$frame.png"
done
post crack-map concrete_beam_fracture.h5 --frame 80 --scale auto -o "$out/fig18_beam_cracks_80.png"
post curve concrete_beam_fracture.h5 --load load:y --load-scale=-1 \
  --displacement mid_bottom:y --displacement-scale=-1e3 -o "$out/fig18_beam_curve.png"
# The damage (softening zone included) near the crack, and which criteria softened it
# (onset strains f_t/E, f_c/E, tau/G of the inputs).
damage() { PYTHONPATH="$IEM_ROOT/postproc" "$IEM_VENV/bin/python" \
  "$IEM_ROOT/postproc/scripts/damage_map.py" "$@" --onsets 1.0e-4,1.0e-3,2.3334e-4; }
damage concrete_cantilever_fracture.h5 --frame 60 --box 0.0,0.3,0.0,0.2 \
  -o "$out/fig17_cantilever_damage_60.png"
damage concrete_beam_fracture.h5 --frame 80 --box 0.45,0.75,0.0,0.2 \
  -o "$out/fig18_beam_damage_80.png"
PYTHONPATH="$IEM_ROOT/postproc" "$IEM_VENV/bin/python" \
  "$IEM_ROOT/postproc/scripts/concrete_beams.py" --dir .
