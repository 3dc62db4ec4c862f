#!/bin/bash
# Run one iem namelist on N MPI ranks under PBS (PBS Pro or Torque), and carry on over the
# time limit: PBS gives no signal ahead of the limit, so iem runs under `timeout`, which
# sends SIGUSR1 (forwarded by mpirun to the ranks) IEM_MARGIN seconds before the walltime;
# iem writes a checkpoint and stops with exit status 4 (a SIGTERM to mpirun works too, see
# run_iem in resubmit.sh), and this script resubmits itself
# with a copy of the case that continues from the checkpoint. Submit from the output folder:
#   qsub -v CASE=path/to/case.nml jobs/pbs_run.sh
#PBS -N iem
#PBS -l select=1:ncpus=16:mpiprocs=16
#PBS -l walltime=01:00:00
#PBS -j oe

# ---- edit for your cluster -----------------------------------------------------------------
# module purge
# module load gcc/12 openmpi/4.1 hdf5-mpi/1.10
IEM_EXE=${IEM_EXE:-$HOME/iem/build/iem}
IEM_RANKS=${IEM_RANKS:-16}
IEM_WALLTIME_S=${IEM_WALLTIME_S:-3600}   # keep equal to walltime above
IEM_MARGIN=${IEM_MARGIN:-300}
IEM_JOB_SCRIPT=${IEM_JOB_SCRIPT:-jobs/pbs_run.sh}
IEM_MAX_RESUBMITS=${IEM_MAX_RESUBMITS:-20}
# ---------------------------------------------------------------------------------------------

set -uo pipefail
cd "${PBS_O_WORKDIR:-.}"
source "$(dirname "$IEM_JOB_SCRIPT")/resubmit.sh"
case_file=${CASE:?usage: qsub -v CASE=case.nml jobs/pbs_run.sh}
check_case "$case_file"
echo "iem: $IEM_EXE on $IEM_RANKS ranks, case $case_file, in $(pwd)"
# --preserve-status: timeout's own status is 124 whatever iem's was
run_iem "$case_file" timeout --preserve-status --signal=USR1 --kill-after=$((IEM_MARGIN - 30)) \
  $((IEM_WALLTIME_S - IEM_MARGIN)) mpirun -np "$IEM_RANKS" "$IEM_EXE" "$case_file"
status=$?
next=$(after_run "$case_file" "$status") || exit "$status"
[ -z "$next" ] && exit 0
qsub -v CASE="$next" "$IEM_JOB_SCRIPT"
