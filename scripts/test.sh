#!/usr/bin/env bash
# Quick start, second command: install what is missing, build, and run the whole test suite
# under CTest (unit tests in pFUnit form, regression runs, the stability suite, bad-input
# corpus, post-processing), except the long cases (label 'long'). `scripts/test.sh --long`
# runs only the long cases. Other arguments go to ctest, e.g. scripts/test.sh -L unit.
# The unit tests build with an installed pFUnit 4 when one is found ($PFUNIT_DIR,
# $CMAKE_PREFIX_PATH, /opt/pfunit), else with the fallback runner in tests/pfunit_lite;
# IEM_USE_PFUNIT=OFF in the environment asks for the fallback.
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
install_packages
make_venv
pfunit=""
[ "${IEM_USE_PFUNIT:-ON}" != OFF ] && pfunit=$(find_pfunit)
if [ -n "$pfunit" ]; then
  runner="pFUnit $(describe_pfunit "$pfunit")"
  # PFUNIT_DIR set exactly, so that a build folder configured before with the fallback (or
  # another pFUnit) is switched over
  unit_options=(-DIEM_USE_PFUNIT=ON "-DPFUNIT_DIR=$pfunit")
  want=pFUnit
else
  runner="fallback runner tests/pfunit_lite (no pFUnit found)"
  [ "${IEM_USE_PFUNIT:-ON}" = OFF ] && runner="fallback runner tests/pfunit_lite (IEM_USE_PFUNIT=OFF)"
  unit_options=(-DIEM_USE_PFUNIT=OFF -UPFUNIT_DIR)
  want=pfunit_lite
fi
build_iem -DIEM_BUILD_TESTS=ON "${unit_options[@]}"
configured=$(sed -n 's/^IEM_UNIT_RUNNER:INTERNAL=//p' "$IEM_BUILD/CMakeCache.txt")
if [[ "$configured" != "$want"* ]]; then
  echo "scripts/test.sh: $IEM_BUILD is configured for '$configured', not $runner" >&2
  exit 1
fi
say "unit tests: $runner"
say "running the tests"
cd "$IEM_BUILD"
if [[ "${1:-}" == "--long" ]]; then
  shift
  ctest --output-on-failure -L long "$@"
else
  ctest --output-on-failure --timeout 900 --parallel 2 -LE long "$@"
fi
