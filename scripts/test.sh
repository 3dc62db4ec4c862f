#!/usr/bin/env bash
# Quick start, second command: install what is missing, build, and run the whole test suite
# under CTest (unit tests in pFUnit form, regression runs, bad-input corpus, post-processing).
# Extra arguments go to ctest, e.g. scripts/test.sh -L unit.
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
install_packages
make_venv
build_iem -DIEM_BUILD_TESTS=ON
say "running the tests"
cd "$IEM_BUILD"
ctest --output-on-failure --timeout 900 "$@"
