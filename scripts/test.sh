#!/usr/bin/env bash
# Quick start, second command: install what is missing, build, and run the whole test suite
# under CTest (unit tests in pFUnit form, regression runs, the stability suite, bad-input
# corpus, post-processing), except the long cases (label 'long'). `scripts/test.sh --long`
# runs only the long cases. Other arguments go to ctest, e.g. scripts/test.sh -L unit.
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
install_packages
make_venv
build_iem -DIEM_BUILD_TESTS=ON
say "running the tests"
cd "$IEM_BUILD"
if [[ "${1:-}" == "--long" ]]; then
  shift
  ctest --output-on-failure -L long "$@"
else
  ctest --output-on-failure --timeout 900 --parallel 2 -LE long "$@"
fi
