# Shared by the job scripts (sourced, not run): what to do after iem has run.
# iem's exit status: 0 done; 4 stopped by SIGTERM/SIGUSR1 after writing its checkpoint;
# 2 bad input; 3 failed (see its message).
: "${IEM_MAX_RESUBMITS:=20}"

# check_case FILE: the case is readable and IEM_EXE runs.
check_case() {
  [ -r "$1" ] || { echo "cannot read $1" >&2; exit 2; }
  [ -x "$IEM_EXE" ] || { echo "IEM_EXE=$IEM_EXE is not an executable" >&2; exit 2; }
}

# value_of FILE KEY: the quoted value of KEY in the namelist FILE (first occurrence).
value_of() {
  sed -n "s/^[^!]*\b$2 *= *['\"]\([^'\"]*\)['\"].*/\1/p" "$1" | head -n 1
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
  local chk out base n next
  chk=$(value_of "$case_file" checkpoint_file)
  if [ -z "$chk" ]; then
    out=$(value_of "$case_file" output_file)
    out=${out:-iem_out.h5}
    base=${out##*/}
    if [[ "$base" == *.* && "$base" != .* ]]; then chk="${out%.*}.chk"; else chk="$out.chk"; fi
  fi
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
