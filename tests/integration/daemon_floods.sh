#!/usr/bin/env bash
# run.sh: weight 0.5 seconds 30
# Bounded floods on loopback (issue 28), each against a daemon with small
# limits so that it stays short; the driver is tests/integration/flood.py.
#
# Parked request bodies: 24 OGC execute requests send 2 MB each and
# stall (the four the budget holds first, the others once it is full).
# With --max-body-memory 8M the daemon holds at most 8 MiB of
# them (its RSS grows by far less than the 48 MB sent; before, each kept
# its buffer: +50 MB), a complete execute request meanwhile gets 503
# naming the flag, and --body-stall-timeout 2 cuts every stalled body
# (before, their average rate kept them for an hour).
#
# Long-lived connections: 240 event streams from 4 addresses, then 240
# uploads sending 200 KB at once and 1 byte/s after, on a daemon of 200
# connections (reserve 20) with --max-streams-per-ip 30: /healthz and a
# job's status keep answering (tests/integration/loris.py probes them every
# second); before, the streams or uploads took every socket.
#
# The oldest streams make room: at --max-streams-per-ip, or at the total
# cap, a new event stream ends the oldest one (of its address, or of all)
# with a final SSE comment naming the Last-Event-ID to reconnect with.
source "$(dirname "$0")/lib.sh"

rss_kb() { awk '/^VmRSS/ { print $2 }' "/proc/$1/status"; }

# ------------------------------------------------------- parked bodies
start_daemon park --workers 1 --max-body-memory 8M --body-stall-timeout 2 ||
    { not_ok "the daemon starts"; exit 1; }
port=${BASE##*:}
rss0=$(rss_kb "$DPID")
printf '{"inputs": {"template": {"value": "%s"}}}' "$(head -c 60000 /dev/zero | tr '\0' A)" \
    >"$WORK/small.json"
# the driver fills the budget, sends the complete execute request
# (small.json) and only then the rest of the flood (why: flood.py)
coproc PARK { python3 "$(dirname "$0")/flood.py" park "$port" 24 2000000 $((6 * SLOW)) \
    "$WORK/small.json" "$WORK/small.out"; }
# its pid and output kept: bash unsets PARK and PARK_PID once the driver
# ends, which a loaded machine can make happen before they are read
park_pid=$PARK_PID
exec {park_out}<&"${PARK[0]}"
read -r -t $((60 * SLOW)) sent code <&"$park_out"
rss1=$(rss_kb "$DPID")
read -r -t $((20 * SLOW)) result <&"$park_out"
wait "$park_pid" 2>/dev/null
exec {park_out}<&-
grown=$(((rss1 - rss0) / 1024))
# uncapped, the 24 buffers alone hold 48 MiB; a sanitizer build also keeps
# freed buffers (the realloc steps) in its quarantine for a while
bound=24
[ "$SLOW" -gt 1 ] && bound=40
if [ "${sent:-}" = sent ] && [ "$grown" -lt "$bound" ]; then
    ok "24 parked execute bodies of 2 MB: the daemon grew by $grown MiB (--max-body-memory 8M)"
else
    not_ok "parked bodies bounded by --max-body-memory" "sent '${sent:-}', grew by $grown MiB"
fi
if [ "$code" = 503 ] && grep -q -- '--max-body-memory' "$WORK/small.out"; then
    ok "an execute request while the budget is taken: 503 naming --max-body-memory"
else
    not_ok "503 past --max-body-memory" "code $code: $(head -c 300 "$WORK/small.out")"
fi
if jq -e --argjson k "$SLOW" '.closed_by_server == .opened and .longest_life <= 2 + 2 * $k' \
    <<<"${result:-null}" >/dev/null; then
    ok "every stalled body cut by --body-stall-timeout 2: $result"
else
    not_ok "stalled bodies cut" "${result:-no result}"
fi
code=$(curl -sS -o "$WORK/small.out" -w '%{http_code}' --max-time 10 -H 'Content-Type: application/json' \
    --data-binary "@$WORK/small.json" "$BASE/v1/processes/match/execution")
check "the budget is back once they are cut (an execute request is read again: $code, not 503)" \
    test "$code" != 503 -a "$code" != 000
stop_daemon

# ------------------------------------------------ long-lived connections
if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
LONGF=(--max-streams-per-ip 30)
[ -n "${SM_TEST_OLD_DAEMON:-}" ] && LONGF=()
start_daemon longlived --workers 1 --max-connections 200 --max-connections-per-ip 100 \
    --reserved-connections 20 "${LONGF[@]}" || { not_ok "the daemon starts"; exit 1; }
port=${BASE##*:}
id=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
poll 30 state_is "$id" running || not_ok "a running job to follow" "$(cat "$WORK/submit.out")"
# its run paused (the worker stopped): the floods hold sockets, as an
# attacker's would; an endless run's ~750 events a second to each of 240
# streams made it a CPU flood too, which an ASan daemon on a loaded machine
# could not answer /healthz through in 2 s
has_worker() { [ -n "$(worker_pid "$id")" ]; }
poll 30 has_worker && kill -STOP "$(worker_pid "$id")"
# A probe answers within 4 s (2 s once: a release daemon at load 45 took
# 2.05 s), and each flood lasts 8 s (3 s once), twice that, so that a probe
# the flood blocked cannot be answered once the flood is over.
PROBE=4
flood() { # MODE SECONDS ADDRS PER DESC
    LORIS_PROBE_SECONDS=$PROBE python3 "$(dirname "$0")/loris.py" "$port" "$2" "$3" "$4" "/v1/jobs/$id" "$1" >"$WORK/$1.json"
    if jq -e --argjson p "$PROBE" '.probes > 0 and .answered == .probes and .max_latency <= $p' "$WORK/$1.json" >/dev/null; then
        ok "$5: $(jq -r '"\(.answered)/\(.probes) probes answered (max \(.max_latency) s)"' "$WORK/$1.json")"
    else
        not_ok "$5" "$(cat "$WORK/$1.json")"
    fi
}
flood stream $((2 * PROBE)) 127.0.0.2,127.0.0.3,127.0.0.4,127.0.0.5 60 \
    "240 event streams from 4 addresses on a 200-connection daemon"
flood bulk $((2 * PROBE)) 127.0.0.6,127.0.0.7,127.0.0.8,127.0.0.9 60 \
    "240 uploads sending 200 KB, then 1 byte/s, from 4 addresses"
hcurl -o /dev/null -X DELETE "$BASE/v1/jobs/$id"
stop_daemon

# ------------------------------------------------ the oldest streams make room
# 2 streams an address, 4 in all (12 connections, 8 reserved): a third
# stream from one address ends that address's oldest, a fifth in all the
# oldest of all, each with a final SSE comment naming the Last-Event-ID
# to reconnect with; the newest are served (before: 503 to the newest)
start_daemon evict --workers 1 --max-connections 12 --reserved-connections 8 \
    --max-streams-per-ip 2 || { not_ok "the daemon starts"; exit 1; }
id=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
poll 30 state_is "$id" running || not_ok "a running job to follow" "$(cat "$WORK/submit.out")"
declare -A SSE_PID
sse() { # NAME ADDRESS: a stream from ADDRESS, once it has its first event
    curl -sS -N --max-time $((30 * SLOW)) --interface "$2" -H 'Accept: text/event-stream' \
        -o "$WORK/sse-$1.txt" -w '%{http_code}' "$BASE/v1/jobs/$id/events" >"$WORK/sse-$1.code" 2>/dev/null &
    SSE_PID[$1]=$!
    poll 10 grep -q '^id:' "$WORK/sse-$1.txt"
}
alive() { kill -0 "${SSE_PID[$1]}" 2>/dev/null; }
evicted() { ! alive "$1" && tail -n 2 "$WORK/sse-$1.txt" | grep -q '^: evicted: .*Last-Event-ID: [0-9]'; }
last_id_ok() { # the comment names the last id the stream sent
    local said sent
    said=$(grep -o 'Last-Event-ID: [0-9]*' "$WORK/sse-$1.txt" | grep -o '[0-9]*$')
    sent=$(grep '^id:' "$WORK/sse-$1.txt" | tail -n 1 | grep -o '[0-9]*')
    [ -n "$said" ] && [ "$said" = "$sent" ]
}
sse a 127.0.0.2
sse b 127.0.0.2
sse c 127.0.0.2
poll 5 evicted a
check "a third stream from one address (--max-streams-per-ip 2) ends that address's oldest with a final comment naming its Last-Event-ID; the newest are served" \
    eval 'evicted a && last_id_ok a && alive b && alive c'
sse d 127.0.0.3
sse e 127.0.0.3
sse f 127.0.0.4
poll 5 evicted b
check "a fifth stream in all (4 = 12 connections - 8 reserved) ends the oldest of all" \
    eval 'evicted b && last_id_ok b && alive c && alive d && alive e && alive f'
hcurl -o /dev/null -X DELETE "$BASE/v1/jobs/$id"
for s in c d e f; do wait "${SSE_PID[$s]}" 2>/dev/null; done
stop_daemon

check "no sanitizer report in the daemon logs" reports_clean
echo "1..$n"
