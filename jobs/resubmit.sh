# Shared by the job scripts (sourced, not run): running iem and what to do after it has run.
# iem's exit status: 0 done; 4 stopped by SIGTERM/SIGUSR1 after writing its checkpoint;
# 2 bad input; 3 failed (see its message).
: "${IEM_MAX_RESUBMITS:=20}"
# Open MPI's mpirun, sent SIGTERM itself, sends the ranks SIGCONT, SIGTERM this many seconds
# later (default 1) and SIGKILL as long again after that: the time iem has to write its
# checkpoint. mpirun returns within about twice this time, with exit status 1 (see run_iem).
export OMPI_MCA_odls_base_sigkill_timeout=${OMPI_MCA_odls_base_sigkill_timeout:-${IEM_TERM_GRACE:-30}}

# check_case FILE: the case is readable and IEM_EXE runs.
check_case() {
  [ -r "$1" ] || { echo "cannot read $1" >&2; exit 2; }
  [ -x "$IEM_EXE" ] || { echo "IEM_EXE=$IEM_EXE is not an executable" >&2; exit 2; }
}

# value_of FILE KEY: the quoted value of KEY in the namelist FILE (first occurrence).
value_of() {
  sed -n "s/^[^!]*\b$2 *= *['\"]\([^'\"]*\)['\"].*/\1/p" "$1" | head -n 1
}

# checkpoint_of CASE: the checkpoint file of the case (checkpoint_file, else output_file with
# the extension .chk).
checkpoint_of() {
  local chk out base
  chk=$(value_of "$1" checkpoint_file)
  if [ -z "$chk" ]; then
    out=$(value_of "$1" output_file)
    out=${out:-iem_out.h5}
    base=${out##*/}
    if [[ "$base" == *.* && "$base" != .* ]]; then chk="${out%.*}.chk"; else chk="$out.chk"; fi
  fi
  echo "$chk"
}

# checkpoint_word FILE N: the N-th (0-based) 64-bit integer of a checkpoint's header; nothing
# when the file cannot be read. 16: its checksum, 17: the signal the run stopped on (0: none).
checkpoint_word() {
  od -An -t d8 -j $((8 * $2)) -N 8 "$1" 2>/dev/null | tr -d ' '
}

# run_iem CASE LAUNCHER...: runs the launcher (mpirun ... iem CASE, srun ..., under timeout or
# not) and returns iem's exit status. mpirun sent SIGTERM exits with 1 whatever its ranks did
# (and timeout, when its time is up, with 124): when the launcher's status is not one of iem's
# (0, 2, 3, 4) but iem rewrote the case's checkpoint on a signal during this run, iem stopped
# as it should, and the status is 4.
run_iem() {
  local case_file=$1 chk before after sig status
  shift
  chk=$(checkpoint_of "$case_file")
  before=$(checkpoint_word "$chk" 16)
  "$@"
  status=$?
  case $status in 0|2|3|4) return "$status" ;; esac
  after=$(checkpoint_word "$chk" 16)
  sig=$(checkpoint_word "$chk" 17)
  if [ -n "$after" ] && [ "$after" != "$before" ] && [ "${sig:-0}" -gt 0 ]; then
    echo "run_iem: the launcher exited with status $status; iem stopped on signal $sig" \
         "after writing $chk: exit status 4" >&2
    return 4
  fi
  return "$status"
}

# after_run CASE STATUS: prints the case file of the next job ('' when the run is done);
# fails when the run failed or when too many jobs have continued it.
after_run() {
  local case_file=$1 status=$2
  [ "$status" -eq 0 ] && { echo ""; return 0; }
  if [ "$status" -ne 4 ]; then
    echo "iem failed with exit status $status; not resubmitting" >&2
    return 1
  fi
  local chk n next
  chk=$(checkpoint_of "$case_file")
  [ -r "$chk" ] || { echo "no checkpoint $chk to continue from" >&2; return 1; }
  # the continuation: the original case (without a restart line) plus restart = 'chk'
  n=$(sed -n 's/^! iem continuation \([0-9]*\)$/\1/p' "$case_file" | head -n 1)
  n=$(( ${n:-0} + 1 ))
  if [ "$n" -gt "$IEM_MAX_RESUBMITS" ]; then
    echo "stopping after $IEM_MAX_RESUBMITS continuations" >&2
    return 1
  fi
  next=${case_file%.nml}
  next="${next%.restart}.restart.nml"
  { echo "! iem continuation $n"
    grep -v -e '^! iem continuation' -e '^ *restart *=' "$case_file" |
      awk -v chk="$chk" '!done && /^ *&run/ { print; print "  restart = \x27" chk "\x27";
                                                done = 1; next } { print }'
  } > "$next.tmp" && mv "$next.tmp" "$next"
  echo "$next"
}
