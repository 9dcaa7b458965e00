#!/usr/bin/env bash
# run.sh: seconds 8 asan 75
# The libFuzzer targets of every parser (tests/fuzz/), built by clang with
# ASan+UBSan into build/fuzz/.  In the release pass each target replays its
# seed corpus (tests/data and tests/fuzz/seeds: format samples, the whole
# malformed corpus, params and payload cases); in the asan pass each one
# also fuzzes for SM_FUZZ_SECONDS (default 2).  `make fuzz` runs them long.
set -u
ROOT=${SM_ROOT:-$(cd "$(dirname "$0")/../.." && pwd)}
cd "$ROOT"
targets=()
for t in build/fuzz/fuzz_*; do
    [ -x "$t" ] && targets+=("$(basename "$t")")
done
if [ "${#targets[@]}" -eq 0 ]; then
    echo "not ok 1 - fuzz targets are built (make fuzz-build)"
    exit 1
fi
seconds=0
# 2 s each: the 14 targets in under a minute with the replays, under the
# sanitizers (a smoke test; `make fuzz` is the real run).
[ "${SM_VARIANT:-release}" = asan ] && seconds=${SM_FUZZ_SECONDS:-2}
exec tests/fuzz/run.sh "$seconds" "${targets[@]}"
