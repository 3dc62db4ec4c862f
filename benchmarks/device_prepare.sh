#!/usr/bin/env bash
# Build what benchmarks/device_scaling.sh runs on a lent many-core machine, into .devrun/
# (git-ignored): the committed tree of HEAD and of a baseline revision (default f17bd0c, the
# code before issue 12), each built twice, for this machine's processor (-march=native) and
# for any x86-64 with AVX2 and FMA (-march=x86-64-v3: the lent machine's processor is not
# known in advance; device_scaling.sh picks the first build that the processor runs), and the
# shared libraries they need that the lent machine lacks (../shared/tools/device-bundle.sh).
#
#   bash benchmarks/device_prepare.sh [BASELINE_REV]
#
# Layout: .devrun/{native,v3}/{new,base}/iem, each with its build's CMakeCache.txt and
# CMakeFiles/iem.dir/flags.make beside it (speed.py reports the compiler and flags from them),
# .devrun/native/flags (the processor features -march=native enabled), .devrun/lib/,
# .devrun/BUILT (the commits). About 2 minutes on 2 cores. Builds use the project's Release
# options with IEM_BUILD_TESTS=OFF.
set -euo pipefail
base_rev=${1:-f17bd0c}
repo="$(git -C "$(dirname "${BASH_SOURCE[0]}")" rev-parse --show-toplevel)"
cd "$repo"
new_sha=$(git rev-parse --verify HEAD)
base_sha=$(git rev-parse --verify "${base_rev}^{commit}")
out=$repo/.devrun
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
rm -rf "$out"
mkdir -p "$out/native" "$out/v3"
for which in new base; do
  sha=$new_sha; [ $which = base ] && sha=$base_sha
  for arch in native v3; do
    src=$work/$which-$arch
    mkdir -p "$src"
    git archive "$sha" | tar -x -C "$src"
    if [ $arch = v3 ]; then
      grep -rl --include=CMakeLists.txt --include='*.cmake' -e '-march=native' "$src" |
        xargs -r sed -i 's/-march=native/-march=x86-64-v3/g'
    fi
    echo "building $which ($sha) for $arch" >&2
    cmake -S "$src" -B "$src/build" -DCMAKE_BUILD_TYPE=Release -DIEM_BUILD_TESTS=OFF >&2
    cmake --build "$src/build" -j "${IEM_BASELINE_JOBS:-2}" --target iem >&2
    dest=$out/$arch/$which
    mkdir -p "$dest/CMakeFiles/iem.dir"
    cp "$src/build/iem" "$src/build/CMakeCache.txt" "$dest/"
    cp "$src/build/CMakeFiles/iem.dir/flags.make" "$dest/CMakeFiles/iem.dir/"
  done
done
# the processor features -march=native turned on here, in /proc/cpuinfo's spelling (those of
# gcc's -m options that match one of this processor's flags once '_' and '.' are dropped):
# device_scaling.sh runs the native builds only where the processor has them all
gfortran -march=native -Q --help=target |
  awk '$2 == "[enabled]" && $1 ~ /^-m/ { sub(/^-m/, "", $1); gsub(/[._]/, "", $1); print $1 }' \
  > "$work/gcc"
grep -m1 '^flags' /proc/cpuinfo | cut -d: -f2 | tr ' ' '\n' | sed '/^$/d' |
  while read -r f; do
    if grep -qx "$(printf '%s' "$f" | tr -d '._')" "$work/gcc"; then echo "$f"; fi
  done > "$out/native/flags"
bash "$repo/../shared/tools/device-bundle.sh" "$out"/native/{new,base}/iem \
  "$out"/v3/{new,base}/iem -o "$out" >&2
printf 'new %s\nbase %s\n' "$new_sha" "$base_sha" > "$out/BUILT"
du -sh "$out"
