#!/usr/bin/env bash
# run.sh: weight 0.25 seconds 30
# Submission limits (issue 8): per tenant with tokens, per client address
# without; --submit-rate per --submit-window and --max-queued unfinished
# jobs answer 429 problem+json with Retry-After; another tenant (address)
# is unaffected; the rate limit lifts when its window has passed, the
# queued limit when a job ends.
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
ok "gmsh builds the test meshes"
TOKENS=$WORK/tokens
printf 'tok-alice alice\ntok-bob bob\n' >"$TOKENS"
# the window holds alice's four submissions (a fixed window from her
# first): 8 s, scaled (once 4 s, which four uploads can take on a loaded
# machine: 0.3-0.9 s each at load 20); the lift is then waited for by its
# Retry-After, not by a guess
WINDOW=$((8 * SLOW))

# post AS-TENANT|--interface ADDR PARAMS: the status; headers in
# $WORK/post.h, body in $WORK/post.json
post() {
    local who=(-H "Authorization: Bearer tok-$1")
    [ "$1" = "${1#--interface}" ] || who=(--interface "${1#--interface=}")
    curl -sS --max-time $((30 * SLOW)) "${who[@]}" -D "$WORK/post.h" -o "$WORK/post.json" \
        -w '%{http_code}' -F "template=@$DISK" -F "target_mesh=@$BOX" -F "target_sol=@$BOXSOL" \
        -F "params=$2" "$BASE/v1/jobs"
}
retry_after() { tr -d '\r' <"$WORK/post.h" | awk -F': ' 'tolower($1) == "retry-after" { print $2 }'; }
problem_names() { # FLAG: a 429 problem+json naming FLAG
    grep -qi '^content-type: application/problem+json' "$WORK/post.h" &&
        jq -e --arg f "$1" '.status == 429 and (.detail | contains($f))' "$WORK/post.json" >/dev/null
}

start_daemon rate --workers 1 --tokens-file "$TOKENS" --submit-rate 3 --submit-window "$WINDOW" \
    --max-queued 0 || { not_ok "the daemon starts"; exit 1; }
ok "a daemon with --submit-rate 3 --submit-window $WINDOW"
codes=
t0=${EPOCHREALTIME/,/.}
for i in 1 2 3; do codes="$codes $(post alice "$(quick_params 5)")"; done
if [ "$codes" = " 201 201 201" ]; then
    ok "alice: three submissions in the window are accepted"
else
    not_ok "alice: three submissions accepted" "codes$codes" "$(cat "$WORK/post.json")"
fi
c=$(post alice "$(quick_params 5)")
ra=$(retry_after)
if [ "$c" = 429 ] && problem_names --submit-rate && [[ $ra =~ ^[0-9]+$ ]] && [ "$ra" -ge 1 ] &&
    [ "$ra" -le "$WINDOW" ]; then
    ok "alice's fourth: 429, Retry-After: $ra (window $WINDOW s): \"$(jq -r .detail "$WORK/post.json")\""
else
    not_ok "alice's fourth: 429 with Retry-After" "code $c, Retry-After '${ra:-}'" "$(cat "$WORK/post.json")"
fi
c=$(post bob "$(quick_params 5)")
if [ "$c" = 201 ]; then
    ok "bob is not limited by alice's rate"
else
    not_ok "bob unaffected" "code $c" "$(cat "$WORK/post.json")"
fi
# the window ends Retry-After seconds after the 429 at the latest
sleep "${ra:-$WINDOW}"
c=$(post alice "$(quick_params 5)")
t1=${EPOCHREALTIME/,/.}
if [ "$c" = 201 ]; then
    ok "alice again after Retry-After: 201 ($(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.1f", b - a }') s after her first)"
else
    not_ok "the rate limit lifts after its window" "code $c" "$(cat "$WORK/post.json")"
fi
stop_daemon

start_daemon queued --workers 1 --tokens-file "$TOKENS" --submit-rate 0 --max-queued 2 ||
    { not_ok "the daemon starts"; exit 1; }
ids=()
for i in 1 2; do
    [ "$(post alice "$(endless_params)")" = 201 ] && ids+=("$(jq -r .jobID "$WORK/post.json")")
done
c=$(post alice "$(endless_params)")
ra=$(retry_after)
if [ "${#ids[@]}" = 2 ] && [ "$c" = 429 ] && problem_names --max-queued && [[ $ra =~ ^[0-9]+$ ]]; then
    ok "--max-queued 2: alice's third unfinished job gets 429 (Retry-After: $ra)"
else
    not_ok "--max-queued: 429" "accepted ${#ids[@]}, code $c" "$(cat "$WORK/post.json")"
fi
c=$(post bob "$(quick_params 5)")
[ "$c" = 201 ] && ok "bob still submits (his own count)" || not_ok "bob unaffected by alice's queue" "code $c"
AUTH=(-H "Authorization: Bearer tok-alice")
hcurl "${AUTH[@]}" -X DELETE -o /dev/null "$BASE/v1/jobs/${ids[1]}"
wait_final "${ids[1]}" 30 || state_is "${ids[1]}" 404
c=$(post alice "$(quick_params 5)")
if [ "$c" = 201 ]; then
    ok "once one of alice's jobs is cancelled, she may submit again"
else
    not_ok "the queued limit lifts when a job ends" "code $c" "$(cat "$WORK/post.json")"
fi
hcurl "${AUTH[@]}" -X DELETE -o /dev/null "$BASE/v1/jobs/${ids[0]}"
stop_daemon

# without tokens: per client address (127.0.0.2 reaches loopback too)
start_daemon addr --workers 1 --submit-rate 2 --submit-window 60 --max-queued 1 ||
    { not_ok "the daemon starts"; exit 1; }
AUTH=()
c1=$(post --interface=127.0.0.1 "$(endless_params)")
first=$(jq -r .jobID "$WORK/post.json")
c2=$(post --interface=127.0.0.1 "$(quick_params 5)")
q=$c2
problem_names --max-queued || q="$c2 (not naming --max-queued)"
c3=$(post --interface=127.0.0.2 "$(quick_params 5)")
if [ "$c1" = 201 ] && [ "$q" = 429 ] && [ "$c3" = 201 ]; then
    ok "no tokens: 127.0.0.1's second unfinished job gets 429, 127.0.0.2 is not limited"
else
    not_ok "per-address queued limit" "codes $c1 $q $c3"
fi
hcurl -X DELETE -o /dev/null "$BASE/v1/jobs/$first"
wait_final "$first" 30 || state_is "$first" 404
poll 30 state_in "$(jq -r .jobID "$WORK/post.json")" successful failed
c4=$(post --interface=127.0.0.2 "$(quick_params 5)")
poll 30 state_in "$(jq -r .jobID "$WORK/post.json")" successful failed
c5=$(post --interface=127.0.0.2 "$(quick_params 5)")
if [ "$c4" = 201 ] && [ "$c5" = 429 ] && problem_names --submit-rate; then
    ok "no tokens: 127.0.0.2's third submission in the minute gets 429 (--submit-rate 2)"
else
    not_ok "per-address rate limit" "codes $c4 $c5" "$(cat "$WORK/post.json")"
fi
if stop_daemon && reports_clean; then
    ok "the daemons stop cleanly, no sanitizer report"
else
    not_ok "clean stop" "$(grep -h 'runtime error\|Sanitizer' "$WORK"/*.log | head -5)"
fi
echo "1..$n"
[ "$failed" -eq 0 ]
