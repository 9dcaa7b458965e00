#!/usr/bin/env bash
# run.sh: weight 1 seconds 40
# The Python package (python/shapematch) with Debian's python3 (stdlib
# unittest, tests/python/, printed as TAP by tests/python/tap.py): match
# against `shapematch run` bit for bit, arrays in = files in, progress and
# stop, errors, the GIL, many matches with a flat RSS, sdf, warp (against
# `shapematch warp` and an exact affine map); image targets against `run
# --target-image` (test_image: match, batch, the Client); templates meshed
# from a surface or a label map (test_template); the Client
# against two real daemons on loopback (one with tokens, one that accepts a
# submission per 2 s: 429 retried) and a fake one answering 503.
# asan: the sanitized libraries under an uninstrumented python3, with the
# runtimes preloaded (leak checks off: the interpreter's own allocations
# would drown ours; the release run measures RSS instead).
source "$(dirname "$0")/lib.sh"

PY=/usr/bin/python3
if [ ! -x "$PY" ]; then
    not_ok "Debian's python3 is installed (/usr/bin/python3; DEB_PACKAGES has python3)"
    exit 1
fi

printf '# tokens of the python suite\npy-secret-%s\n' $$ >"$WORK/tokens"
TOKEN=$(sed -n 2p "$WORK/tokens")
if start_daemon py --workers 2 --tokens-file "$WORK/tokens"; then
    ok "daemon with tokens started ($BASE)"
else
    not_ok "daemon with tokens started"
    exit 1
fi
MAIN=$BASE
SPOOL=
if start_daemon rate --workers 1 --tokens-file "$WORK/tokens" --submit-rate 1 --submit-window 2; then
    ok "rate-limited daemon started ($BASE)"
else
    not_ok "rate-limited daemon started"
    exit 1
fi

env=(SM_BIN="$BIN" SM_ROOT="$ROOT" SM_VARIANT="$VARIANT" SHAPEMATCH_LIBDIR="$BIN"
    SM_TEST_DAEMON="$MAIN" SM_TEST_TOKEN="$TOKEN" SM_TEST_DAEMON_RATE="$BASE")
if [ "$VARIANT" = asan ]; then
    env+=(LD_PRELOAD="$(gcc -print-file-name=libasan.so) $(gcc -print-file-name=libubsan.so)"
        ASAN_OPTIONS="detect_leaks=0:halt_on_error=1")
fi
# the suite's own TAP lines, renumbered after ours
while IFS= read -r line; do
    case $line in
    "ok "*) ok "${line#ok [0-9]* - }" ;;
    "not ok "*) not_ok "${line#not ok [0-9]* - }" ;;
    "1.."*) ;;
    *) echo "$line" ;;
    esac
done < <(env "${env[@]}" "$PY" "$ROOT/tests/python/tap.py" test_shapematch test_inputs test_warp test_image test_template test_client \
    2>"$WORK/py.err"; echo "# python exit $?" >"$WORK/py.rc")
if grep -qx '# python exit 0' "$WORK/py.rc"; then
    ok "the Python tests ran to their end"
else
    not_ok "the Python tests ran to their end" "$(cat "$WORK/py.rc")" "$(tail -30 "$WORK/py.err")"
fi
if grep -q 'Sanitizer\|runtime error' "$WORK/py.err"; then
    not_ok "no sanitizer report" "$(grep -A20 'Sanitizer\|runtime error' "$WORK/py.err" | head -40)"
else
    ok "no sanitizer report"
fi
[ "$failed" -eq 0 ]
