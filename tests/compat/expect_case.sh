#!/usr/bin/env bash
# Runs one case of a compat_published_tests binary in a process of its own and checks how it
# ends: `pass` (gtest reports it passed), `fail` (gtest reports it failed because the drop-in
# threw) or `abort REGEX` (the program stopped at an assertion whose text matches REGEX).
# Usage: expect_case.sh BINARY CASE pass|fail|abort [REGEX]
set -uo pipefail
binary=$1 case_name=$2 expected=$3 regex=${4:-}
output=$("$binary" --gtest_filter="ControllerTests.$case_name" 2>&1)
status=$?
echo "$output"
echo "exit status $status; expected: $expected $regex"
case $expected in
  pass)
    [[ $status -eq 0 ]] && grep -q '^\[  PASSED  \] 1 test\.' <<<"$output" ;;
  fail)
    [[ $status -eq 1 ]] && grep -q "^\[  FAILED  \] ControllerTests\.$case_name " <<<"$output" &&
      grep -q 'cartesian_impedance::Error\|threw an exception\|C++ exception' <<<"$output" ;;
  abort)
    [[ $status -gt 128 ]] && grep -q 'Assertion' <<<"$output" && grep -qE "$regex" <<<"$output" ;;
  *)
    echo "unknown expectation $expected"; exit 2 ;;
esac
