#!/usr/bin/env bash
# `make demo`: the whole system on one machine.  Starts shapematchd on a
# free loopback port with a spool under build/, submits the bundled 2D
# example (a disk matched onto a star) with the client, shows its progress
# live, fetches the results into demo-out/ and stops the daemon again -
# also when something fails or on Ctrl-C.
#
# Env (all optional): SM_BIN     folder of the programs (build/release)
#                     DEMO_OUT   results folder (demo-out)
#                     DEMO_SPOOL daemon spool (build/demo-spool; emptied first)
set -euo pipefail

# paths given by the caller are relative to the caller's folder
here=$PWD
absolute() { case $1 in /*) printf '%s\n' "$1" ;; *) printf '%s\n' "$here/$1" ;; esac; }
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BIN=$(absolute "${SM_BIN:-$ROOT/build/release}")
OUT=$(absolute "${DEMO_OUT:-$ROOT/demo-out}")
SPOOL=$(absolute "${DEMO_SPOOL:-$ROOT/build/demo-spool}")
LOG=$SPOOL.log
cd "$ROOT"
EX=examples/2d
# sanitizer builds are several times slower
SLOW=1
case $BIN in *asan*) SLOW=4 ;; esac

say() { printf '%s\n' "$*"; }
die() { printf 'demo: %s\n' "$*" >&2; exit 1; }

for p in shapematchd shapematch-worker shapematch; do
    [ -x "$BIN/$p" ] || die "$BIN/$p is missing: run 'make demo' (or 'make release') first"
done
for f in template.mesh background.mesh.gz background.sol.gz clamp; do
    [ -f "$EX/$f" ] || die "$EX/$f is missing"
done

# ---------------------------------------------------------------- the daemon
DPID=
CPID=
stop_all() {
    # the client first (it may be following the job), then the daemon:
    # SIGTERM, its graceful stop, SIGKILL only if it hangs
    if [ -n "$CPID" ] && kill -0 "$CPID" 2>/dev/null; then
        kill -TERM "$CPID" 2>/dev/null || true
        wait "$CPID" 2>/dev/null || true
    fi
    CPID=
    [ -n "$DPID" ] || return 0
    if kill -0 "$DPID" 2>/dev/null; then
        kill -TERM "$DPID" 2>/dev/null || true
        local i
        for ((i = 0; i < 150; i++)); do
            kill -0 "$DPID" 2>/dev/null || break
            sleep 0.1
        done
        if kill -0 "$DPID" 2>/dev/null; then
            say "demo: shapematchd did not stop within 15 s: killed" >&2
            kill -KILL "$DPID" 2>/dev/null || true
        fi
    fi
    wait "$DPID" 2>/dev/null || true
    say "shapematchd (pid $DPID) stopped"
    DPID=
}
trap stop_all EXIT
trap 'say "demo: interrupted" >&2; exit 130' INT
trap 'say "demo: terminated" >&2; exit 143' TERM

# A fresh spool each time: a job of an earlier, interrupted demo must not
# run again.  Only a folder this script made (it holds the marker) is
# removed, so a mistyped DEMO_SPOOL cannot empty someone's folder.
if [ -e "$SPOOL" ]; then
    [ -f "$SPOOL/DEMO-SPOOL" ] || die "$SPOOL exists and is not a demo spool: choose another DEMO_SPOOL"
    rm -rf "$SPOOL"
fi
mkdir -p "$SPOOL"
echo "spool of examples/demo.sh, emptied by every run" >"$SPOOL/DEMO-SPOOL"
mkdir -p "$OUT"
rm -f "$OUT"/{result.mesh,result.vtu,displacement.sol,history.csv,summary.json}

# port 0: the kernel picks a free port, the daemon logs which (the log is
# emptied here, not by the redirection, so that the line read below cannot
# be one of an earlier run)
: >"$LOG"
# (without SHAPEMATCH_* settings of the caller's environment: this daemon
# and the client below are configured by their flags alone)
unset_settings=()
for v in $(compgen -e | grep '^SHAPEMATCH_' || true); do unset_settings+=(-u "$v"); done
env "${unset_settings[@]}" "$BIN/shapematchd" --listen 127.0.0.1:0 --spool "$SPOOL" --workers 1 \
    --shutdown-grace 2s --kill-grace 1s 2>>"$LOG" &
DPID=$!
port=
for ((i = 0; i < 200 * SLOW; i++)); do
    port=$(sed -n 's/.*"event":"listening".*"port":\([0-9][0-9]*\).*/\1/p' "$LOG" | tail -1)
    [ -n "$port" ] && break
    kill -0 "$DPID" 2>/dev/null || break
    sleep 0.05
done
if [ -z "$port" ]; then
    sed 's/^/  /' "$LOG" >&2
    die "shapematchd did not start (log above, in $LOG)"
fi
SERVER=http://127.0.0.1:$port
say "shapematchd (pid $DPID) listening on $SERVER"
say "  spool $SPOOL, log $LOG"

# ------------------------------------------------------------------- the job
clamp=$(tr -d ' \n' <"$EX/clamp")
say
say "submitting $EX: template.mesh (a disk) onto the star given by background.sol.gz,"
say "clamped in the disk ($clamp), until the L2 norm of d on the boundary is <= 1e-4"
say

# The client runs in the background so that Ctrl-C (or SIGTERM) reaches
# the trap at once; the trap stops it.
env "${unset_settings[@]}" "$BIN/shapematch" submit --server "$SERVER" \
    --template "$EX/template.mesh" \
    --target-mesh "$EX/background.mesh.gz" \
    --target-sol "$EX/background.sol.gz" \
    --clamp-ball "$clamp" --tol-boundary 1e-4 \
    --wait -o "$OUT" &
CPID=$!
rc=0
wait "$CPID" || rc=$?
CPID=
[ "$rc" -eq 0 ] || die "the client failed (exit $rc); daemon log: $LOG"

# ------------------------------------------------------------------- results
say
say "results in $OUT/:"
for f in result.mesh result.vtu displacement.sol history.csv summary.json; do
    [ -s "$OUT/$f" ] || die "$OUT/$f is missing"
    printf '  %-18s %9d bytes\n' "$f" "$(wc -c <"$OUT/$f")"
done
# the figures by their names in summary.json: the two-sided distances
# (in the meshes' unit), then the L2 norm that --tol-boundary compares
IFS=$'\t' read -r stop iterations rt tr p99 boundary j_initial j_final < <(jq -r \
    '[.stop_reason, .iterations, .distance.result_to_target.rms, .distance.target_to_result.rms,
      .distance.target_to_result.p99, .boundary_l2, .J_initial, .J_final] | @tsv' "$OUT/summary.json") ||
    die "$OUT/summary.json is not the expected JSON"
printf 'summary: %s after %d iterations: result->target RMS %.3g, target->result RMS %.3g (p99 %.3g); L2 of d on the boundary %.3g; J %.6g -> %.6g\n' \
    "$stop" "$iterations" "$rt" "$tr" "$p99" "$boundary" "$j_initial" "$j_final"
say "open $OUT/result.vtu in ParaView, or $OUT/result.mesh in Gmsh or Medit"
say
stop_all
