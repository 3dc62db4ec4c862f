#!/usr/bin/env bash
# Quick start, first command: install what is missing, build, run the default scene
# (inputs/cantilever_elastic.nml) and write its plots into run/.
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
install_packages
make_venv
build_iem -DIEM_BUILD_TESTS=OFF
mkdir -p "$IEM_ROOT/run"
cd "$IEM_ROOT/run"
n=$(demo_ranks)
say "running the default scene on $n ranks: mpirun -np $n build/iem inputs/cantilever_elastic.nml"
mpirun -np "$n" "$IEM_BUILD/iem" "$IEM_ROOT/inputs/cantilever_elastic.nml"
say "plotting"
"$IEM_VENV/bin/iem-post" all cantilever_elastic.h5 -o plots
"$IEM_VENV/bin/iem-post" summary cantilever_elastic.h5
say "done: run/cantilever_elastic.h5 (open run/cantilever_elastic.xmf in ParaView) and run/plots/"
