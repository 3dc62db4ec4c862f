#!/usr/bin/env bash
# Build a given git revision of this repository once, as a baseline to compare against, and
# print the path of its iem executable (the only line on stdout; the build's output goes to
# stderr).
#
#   bash benchmarks/baseline.sh [REV] [-- EXTRA_CMAKE_ARGS...]
#
# REV defaults to 23b6112 (the code before the lattice rewrite of issue 10). The revision's
# committed tree (git archive: no uncommitted change, no untracked file) is unpacked and
# built with the project's plain options, -DCMAKE_BUILD_TYPE=Release -DIEM_BUILD_TESTS=OFF
# (plus EXTRA_CMAKE_ARGS), under
#   ${IEM_BASELINE_DIR:-<repository root>/build/baselines}/baseline-<12-digit sha>[-<args hash>]/
# (build/ is ignored by git, so this is outside the tracked source tree), and the folder is
# reused when a finished build is there (it holds the file DONE). Builds use
# ${IEM_BASELINE_JOBS:-2} jobs. Two calls for the same folder wait for each other (flock).
# Exit status: 0 with the path printed, 1 when the revision is unknown or the build fails.
set -euo pipefail

rev="23b6112"
if [[ $# -gt 0 && "$1" != "--" ]]; then rev="$1"; shift; fi
if [[ $# -gt 0 && "$1" == "--" ]]; then shift; fi
extra=("$@")

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(git -C "$here" rev-parse --show-toplevel)"
sha="$(git -C "$repo" rev-parse --verify --quiet "${rev}^{commit}")" || {
  echo "baseline.sh: error: '${rev}' is not a commit of ${repo}" >&2
  exit 1
}
root="${IEM_BASELINE_DIR:-${repo}/build/baselines}"
name="baseline-${sha:0:12}"
if [[ ${#extra[@]} -gt 0 ]]; then
  name="${name}-$(printf '%s\n' "${extra[@]}" | sha1sum | cut -c1-8)"
fi
dir="${root}/${name}"
exe="${dir}/build/iem"
mkdir -p "$dir"

exec 9>"${dir}/.lock"
flock 9
if [[ -f "${dir}/DONE" && -x "$exe" ]]; then
  echo "baseline.sh: reusing ${dir} (${sha:0:12})" >&2
  echo "$exe"
  exit 0
fi

echo "baseline.sh: building ${sha:0:12} ($(git -C "$repo" log -1 --format=%s "$sha" | cut -c1-60)) in ${dir}" >&2
rm -rf "${dir}/src" "${dir}/build" "${dir}/DONE"
mkdir -p "${dir}/src"
git -C "$repo" archive --format=tar "$sha" | tar -x -C "${dir}/src"
{
  cmake -S "${dir}/src" -B "${dir}/build" -DCMAKE_BUILD_TYPE=Release -DIEM_BUILD_TESTS=OFF \
    "${extra[@]}"
  cmake --build "${dir}/build" -j "${IEM_BASELINE_JOBS:-2}" --target iem
} 1>&2 || {
  echo "baseline.sh: error: the build of ${sha:0:12} failed (folder ${dir})" >&2
  exit 1
}
{
  echo "commit ${sha}"
  echo "cmake -DCMAKE_BUILD_TYPE=Release -DIEM_BUILD_TESTS=OFF ${extra[*]}"
  date -u +"built %Y-%m-%dT%H:%M:%SZ"
} >"${dir}/DONE"
echo "$exe"
