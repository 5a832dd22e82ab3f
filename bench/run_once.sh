#!/usr/bin/env bash
# The ctest `benchmarks_run`: every benchmark once, briefly (no figure is judged here; speed is
# read from a full run, README "Performance"). It fails if the program fails or a benchmark
# reports an error: each checks that what it timed did its work (no fault, the loop acted, the
# control thread ran), so a benchmark that quietly measures a failing path is caught.
set -uo pipefail
output=$("$1" --benchmark_min_time=0.001 2>&1)
status=$?
printf '%s\n' "$output"
if [ $status -ne 0 ]; then
  echo "benchmarks_run: the program exited with $status" >&2
  exit 1
fi
if grep -q "ERROR OCCURRED" <<< "$output"; then
  echo "benchmarks_run: a benchmark reported an error (above)" >&2
  exit 1
fi
