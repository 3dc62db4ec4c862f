#!/bin/bash
# Run one iem namelist on N MPI ranks under SLURM. Builds nothing: point IEM_EXE at an
# installed or built iem. Submit from the folder where the output should go:
#   sbatch --ntasks=64 jobs/slurm_run.sh path/to/case.nml
#SBATCH --job-name=iem
#SBATCH --ntasks=16
#SBATCH --time=01:00:00
#SBATCH --output=iem-%j.out
#SBATCH --error=iem-%j.err

# ---- edit for your cluster: the modules iem was built with ----------------------------------
# module purge
# module load gcc/12 openmpi/4.1 hdf5-mpi/1.10 metis/5.1
IEM_EXE=${IEM_EXE:-$HOME/iem/build/iem}
# ---------------------------------------------------------------------------------------------

set -euo pipefail
case_file=${1:?usage: sbatch [options] jobs/slurm_run.sh case.nml}
[ -r "$case_file" ] || { echo "cannot read $case_file" >&2; exit 2; }
[ -x "$IEM_EXE" ] || { echo "IEM_EXE=$IEM_EXE is not an executable" >&2; exit 2; }
echo "iem: $IEM_EXE on ${SLURM_NTASKS} ranks, case $case_file, in $(pwd)"
srun --ntasks="${SLURM_NTASKS}" "$IEM_EXE" "$case_file"
