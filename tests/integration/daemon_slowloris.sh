#!/usr/bin/env bash
# run.sh: weight 0.5 seconds 25
# Slow clients cannot starve the daemon (issue 8): 400 sockets from four
# loopback addresses (100 each, under --max-connections-per-ip) trickle
# one header byte per second for 6 s (twice --header-timeout) and fill
# --max-connections; /healthz
# and a job's status (from 127.0.0.1, a fresh connection each) keep
# answering within 2 s, every trickling socket is closed by
# --header-timeout, and the reserve keeps room; then uploads trickling
# their body at 1 byte/s are cut by --min-upload-rate.  The driver is
# tests/integration/loris.py.  Before these deadlines the same attack got
# 0 of 10 probes answered.
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
ok "gmsh builds the test meshes"
HT=3
start_daemon loris --workers 1 --max-connections 400 --max-connections-per-ip 100 \
    --header-timeout "$HT" --min-upload-rate 1K || { not_ok "the daemon starts"; exit 1; }
port=${BASE##*:}
id=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)")
if [ -n "$id" ] && wait_final "$id" 60; then
    ok "a job to probe"
else
    not_ok "a job to probe" "$(cat "$WORK/submit.out")"
fi

# attack MODE SECONDS ADDRS PER: the driver's JSON in $WORK/MODE.json
attack() {
    python3 "$(dirname "$0")/loris.py" "$port" "$2" "$3" "$4" "/v1/jobs/$id" "$1" >"$WORK/$1.json"
}
# verdict MODE DESC: every probe answered within 2 s, sockets cut by the
# deadline (none lived past it by more than two sweeps' slack)
verdict() {
    local j=$WORK/$1.json
    if jq -e --argjson ht "$HT" --argjson k "$SLOW" '.probes > 0 and .answered == .probes and
        .max_latency <= 2 and .closed_by_server > 0 and .longest_life <= $ht + 2 * $k' "$j" >/dev/null; then
        ok "$2: $(jq -r '"\(.answered)/\(.probes) probes answered (max \(.max_latency) s, median \(.median_latency) s); \(.opened) sockets opened, \(.closed_by_server) cut, longest \(.longest_life) s"' "$j")"
    else
        not_ok "$2" "$(cat "$j")"
    fi
}
attack headers 6 127.0.0.2,127.0.0.3,127.0.0.4,127.0.0.5 100
verdict headers "slow-loris, 400 sockets from 4 addresses sending a header byte per second"
attack body 5 127.0.0.6,127.0.0.7 20
verdict body "40 uploads sending their body at 1 byte/s"

curl -sS --max-time 10 "$BASE/metrics" >"$WORK/metrics.txt"
cuts() { awk -v r="$1" '$1 == "shapematch_connections_cut_total{reason=\"" r "\"}" { print $2 }' "$WORK/metrics.txt"; }
if [ "$(cuts header_timeout)" -gt 0 ] 2>/dev/null && [ "$(cuts slow_body)" -gt 0 ] 2>/dev/null; then
    ok "/metrics counts the cuts: header_timeout $(cuts header_timeout), slow_body $(cuts slow_body), reserve $(cuts reserve)"
else
    not_ok "/metrics counts the cuts" "$(grep connections "$WORK/metrics.txt")"
fi
id2=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)")
if [ -n "$id2" ] && wait_final "$id2" 60 && state_is "$id2" successful; then
    ok "an ordinary upload is accepted and runs after the attack"
else
    not_ok "an ordinary upload after the attack" "$(cat "$WORK/submit.out")"
fi
if stop_daemon && reports_clean; then
    ok "SIGTERM stops the daemon, no sanitizer report"
else
    not_ok "clean stop"
fi
echo "1..$n"
[ "$failed" -eq 0 ]
