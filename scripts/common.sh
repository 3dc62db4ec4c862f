# Shared by scripts/demo.sh and scripts/test.sh: install what is missing, make the Python
# venv, configure and build. Source it; do not run it.
set -euo pipefail

IEM_ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
IEM_BUILD=${IEM_BUILD:-$IEM_ROOT/build}
IEM_VENV=${IEM_VENV:-$IEM_ROOT/.venv}
# m4 and python3 are needed to build pFUnit (.ci/run builds it from ../shared/vendor/pfunit)
IEM_PACKAGES="gfortran cmake make libopenmpi-dev openmpi-bin libhdf5-openmpi-dev hdf5-tools
  python3 python3-venv python3-pip m4"
# Open MPI refuses root unless told; harmless otherwise.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_rmaps_base_oversubscribe=1

say() { printf '\n== %s\n' "$*"; }

# Install the Debian/Ubuntu packages that are missing (as root, or through sudo).
install_packages() {
  local missing=() p
  for p in $IEM_PACKAGES; do
    dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
  done
  if [ ${#missing[@]} -eq 0 ]; then
    say "system packages: all present"
    return
  fi
  say "installing: ${missing[*]}"
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || { echo "need root or sudo to install ${missing[*]}" >&2; exit 1; }
    sudo="sudo"
  fi
  $sudo env DEBIAN_FRONTEND=noninteractive apt-get update -qq
  $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
    "${missing[@]}" >/dev/null
}

# Make (or reuse) the venv with the post-processing and test needs.
make_venv() {
  if [ ! -x "$IEM_VENV/bin/python" ]; then
    say "creating the Python environment $IEM_VENV"
    python3 -m venv "$IEM_VENV"
  fi
  if ! "$IEM_VENV/bin/python" -c "import h5py, numpy, matplotlib, pytest, iem_post" 2>/dev/null; then
    say "installing Python packages"
    "$IEM_VENV/bin/python" -m pip install -q --upgrade pip
    "$IEM_VENV/bin/python" -m pip install -q -e "$IEM_ROOT/postproc[test]"
  fi
}

# Configure and build (Release unless IEM_BUILD_TYPE says otherwise).
build_iem() {
  say "configuring and building in $IEM_BUILD"
  cmake -S "$IEM_ROOT" -B "$IEM_BUILD" -DCMAKE_BUILD_TYPE="${IEM_BUILD_TYPE:-Release}" \
    -DPython3_EXECUTABLE="$IEM_VENV/bin/python" "$@" >/dev/null
  cmake --build "$IEM_BUILD" -j "$(nproc)"
}

# The directory holding PFUNITConfig.cmake of an installed pFUnit 4, looked for in $PFUNIT_DIR
# (that directory or a prefix), each entry of $CMAKE_PREFIX_PATH, then /opt/pfunit; prints
# nothing when there is none.
find_pfunit() {
  local places=() p cfg
  [ -n "${PFUNIT_DIR:-}" ] && places+=("$PFUNIT_DIR")
  if [ -n "${CMAKE_PREFIX_PATH:-}" ]; then
    IFS=':;' read -r -a p <<<"$CMAKE_PREFIX_PATH"
    places+=("${p[@]}")
  fi
  places+=(/opt/pfunit)
  for p in "${places[@]}"; do
    [ -n "$p" ] || continue
    for cfg in "$p/PFUNITConfig.cmake" "$p"/PFUNIT-4*/cmake/PFUNITConfig.cmake \
               "$p"/lib*/cmake/PFUNIT*/PFUNITConfig.cmake; do
      if [ -f "$cfg" ]; then
        dirname "$cfg"
        return
      fi
    done
  done
}

# "4.14 from /opt/pfunit" for the pFUnit whose PFUNITConfig.cmake is in directory $1.
describe_pfunit() {
  local version
  version=$(sed -n 's/.*set(PACKAGE_VERSION "\([0-9]*\.[0-9]*\).*/\1/p' \
            "$1/PFUNITConfig-version.cmake" 2>/dev/null | head -n 1)
  case "$1" in
    */PFUNIT-*/cmake) echo "${version:-4} from ${1%/PFUNIT-*/cmake}" ;;
    *) echo "${version:-4} from $1" ;;
  esac
}

# Number of ranks for the demo: 2 where there are 2 cores, else 1.
demo_ranks() {
  local n
  n=$(nproc)
  [ "$n" -ge 2 ] && echo 2 || echo 1
}
