#!/bin/bash
# Run one iem namelist on N MPI ranks under SLURM, and carry on over the time limit:
# SLURM sends SIGUSR1 to the ranks 300 s before the limit (--signal), iem writes a checkpoint
# and stops with exit status 4, and this script resubmits itself with a copy of the case
# that continues from the checkpoint (restart = '...'). Builds nothing: point IEM_EXE at an
# installed or built iem. Submit from the folder where the output should go:
#   sbatch --ntasks=64 jobs/slurm_run.sh path/to/case.nml
# (set IEM_JOB_SCRIPT if this script is not at jobs/slurm_run.sh below that folder).
#SBATCH --job-name=iem
#SBATCH --ntasks=16
#SBATCH --time=01:00:00
#SBATCH --signal=USR1@300
#SBATCH --output=iem-%j.out
#SBATCH --error=iem-%j.err

# ---- edit for your cluster: the modules iem was built with ----------------------------------
# module purge
# module load gcc/12 openmpi/4.1 hdf5-mpi/1.10
IEM_EXE=${IEM_EXE:-$HOME/iem/build/iem}
IEM_JOB_SCRIPT=${IEM_JOB_SCRIPT:-jobs/slurm_run.sh}
IEM_MAX_RESUBMITS=${IEM_MAX_RESUBMITS:-20}
# ---------------------------------------------------------------------------------------------

set -uo pipefail
here=$(dirname "$0")
source "${SLURM_SUBMIT_DIR:-.}/$(dirname "$IEM_JOB_SCRIPT")/resubmit.sh" 2>/dev/null ||
  source "$here/resubmit.sh"
case_file=${1:?usage: sbatch [options] jobs/slurm_run.sh case.nml}
check_case "$case_file"
echo "iem: $IEM_EXE on ${SLURM_NTASKS} ranks, case $case_file, in $(pwd)"
run_iem "$case_file" srun --ntasks="${SLURM_NTASKS}" "$IEM_EXE" "$case_file"
status=$?
next=$(after_run "$case_file" "$status") || exit "$status"
[ -z "$next" ] && exit 0
sbatch --ntasks="${SLURM_NTASKS}" "$IEM_JOB_SCRIPT" "$next"
