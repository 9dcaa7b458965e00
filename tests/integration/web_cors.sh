#!/usr/bin/env bash
# Browsers and shapematchd (issue 11), with curl: CORS preflights answer
# 204 with the route's methods (from the route table), the allowed request
# headers and a Max-Age; responses carry Access-Control-Allow-Origin and
# the exposed headers for listed origins only, and Vary: Origin always;
# a POST or DELETE from a foreign Origin gets 403 (tokens on or off),
# one from the daemon's own origin (Host, or --public-url) or without
# Origin is unaffected; '*' is refused with tokens; the access_token query
# parameter authenticates GET routes (events, results) and never reaches
# the daemon's log or the metrics.
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
ok "gmsh builds the test meshes"

APP=http://app.example.test:5173
# hdr NAME: the value of a header in $WORK/h (last one, CR stripped)
hdr() { tr -d '\r' <"$WORK/h" | awk -v n="$1" 'BEGIN { n = tolower(n) } { i = index($0, ":"); if (tolower(substr($0, 1, i - 1)) == n) v = substr($0, i + 2) } END { print v }'; }
has_hdr() { tr -d '\r' <"$WORK/h" | grep -qi "^$1:"; }
# req METHOD URL [CURL ARGS]: the status; headers in $WORK/h, body in $WORK/b
req() {
    local m=$1 u=$2
    shift 2
    curl -sS --max-time $((10 * SLOW)) -X "$m" -D "$WORK/h" -o "$WORK/b" -w '%{http_code}' "$@" "$u"
}

# ------------------------------------------------------ an open daemon
start_daemon open --workers 1 --cors-origin "$APP" --cors-origin http://other.example.test \
    || { not_ok "the daemon starts with --cors-origin"; exit 1; }
ok "the daemon starts with two --cors-origin"

c=$(req OPTIONS "$BASE/v1/jobs" -H "Origin: $APP" -H 'Access-Control-Request-Method: POST' \
    -H 'Access-Control-Request-Headers: authorization, idempotency-key')
if [ "$c" = 204 ] && [ "$(hdr Access-Control-Allow-Origin)" = "$APP" ] &&
    [ "$(hdr Access-Control-Allow-Methods)" = "GET, HEAD, POST, OPTIONS" ] &&
    hdr Access-Control-Allow-Headers | grep -q 'Authorization, Content-Type, Idempotency-Key, Last-Event-ID, Prefer' &&
    [ "$(hdr Access-Control-Max-Age)" = 600 ] && hdr Vary | grep -q Origin; then
    ok "preflight of POST /v1/jobs from a listed origin: 204, the route's methods, headers, Max-Age, Vary"
else
    not_ok "preflight of /v1/jobs" "code $c" "$(cat "$WORK/h")"
fi
c=$(req OPTIONS "$BASE/v1/jobs/0123456789abcdef0123456789abcdef" -H "Origin: $APP" \
    -H 'Access-Control-Request-Method: DELETE')
if [ "$c" = 204 ] && [ "$(hdr Access-Control-Allow-Methods)" = "GET, HEAD, DELETE, OPTIONS" ]; then
    ok "preflight of a job: GET, HEAD, DELETE (its rows of the route table)"
else
    not_ok "preflight of a job" "code $c" "$(cat "$WORK/h")"
fi
c=$(req OPTIONS "$BASE/v1/jobs/0123456789abcdef0123456789abcdef/events" -H "Origin: $APP")
if [ "$c" = 204 ] && [ "$(hdr Access-Control-Allow-Methods)" = "GET, HEAD, OPTIONS" ]; then
    ok "preflight of the events: GET, HEAD"
else
    not_ok "preflight of the events" "code $c" "$(cat "$WORK/h")"
fi
c=$(req OPTIONS "$BASE/v1/jobs" -H 'Origin: http://evil.example.test' -H 'Access-Control-Request-Method: POST')
if [ "$c" = 204 ] && ! has_hdr Access-Control-Allow-Origin && ! has_hdr Access-Control-Allow-Methods &&
    [ "$(hdr Allow)" = "GET, HEAD, POST, OPTIONS" ]; then
    ok "preflight from an unlisted origin: 204 with Allow, no CORS headers (the browser refuses)"
else
    not_ok "preflight from an unlisted origin" "code $c" "$(cat "$WORK/h")"
fi
c=$(req OPTIONS "$BASE/v1/nothing" -H "Origin: $APP")
check "OPTIONS on no route: 404" [ "$c" = 404 ]

c=$(req GET "$BASE/v1/processes" -H "Origin: $APP")
if [ "$c" = 200 ] && [ "$(hdr Access-Control-Allow-Origin)" = "$APP" ] &&
    [ "$(hdr Access-Control-Expose-Headers)" = "Location, Preference-Applied, Retry-After, Content-Disposition" ] &&
    tr -d '\r' <"$WORK/h" | grep -i '^vary:' | grep -q Origin; then
    ok "GET from a listed origin: Allow-Origin echoes it, exposed headers, Vary: Origin"
else
    not_ok "GET from a listed origin" "code $c" "$(cat "$WORK/h")"
fi
c=$(req GET "$BASE/v1/processes" -H 'Origin: http://evil.example.test')
if [ "$c" = 200 ] && ! has_hdr Access-Control-Allow-Origin && ! has_hdr Access-Control-Expose-Headers &&
    tr -d '\r' <"$WORK/h" | grep -i '^vary:' | grep -q Origin; then
    ok "GET from an unlisted origin: no CORS headers, Vary: Origin"
else
    not_ok "GET from an unlisted origin" "code $c" "$(cat "$WORK/h")"
fi
c=$(req GET "$BASE/v1/processes")
if [ "$c" = 200 ] && ! has_hdr Access-Control-Allow-Origin; then
    ok "GET without Origin: no CORS headers"
else
    not_ok "GET without Origin" "code $c" "$(cat "$WORK/h")"
fi

# cross-site safety, tokens off
form=(-F "template=@$DISK" -F "target_mesh=@$BOX" -F "target_sol=@$BOXSOL" -F "params=$(quick_params 5)")
c=$(req POST "$BASE/v1/jobs" -H 'Origin: http://evil.example.test' "${form[@]}")
if [ "$c" = 403 ] && jq -e '.status == 403 and (.detail | test("cross-site"))' "$WORK/b" >/dev/null &&
    [ "$(hdr Content-Type)" = application/problem+json ] &&
    [ "$(hcurl "$BASE/v1/jobs" | jq '.jobs | length')" = 0 ]; then
    ok "POST /v1/jobs from a foreign origin without tokens: 403 problem+json, no job made"
else
    not_ok "a foreign POST is refused" "code $c" "$(cat "$WORK/b")"
fi
c=$(req POST "$BASE/v1/jobs" -H 'Origin: null' "${form[@]}")
check "POST with Origin: null (sandboxed page, file:): 403" [ "$c" = 403 ]
c=$(req POST "$BASE/v1/jobs" -H "Origin: $APP" "${form[@]}")
A=$(jq -r '.jobID // empty' "$WORK/b")
if [ "$c" = 201 ] && [ -n "$A" ] && [ "$(hdr Access-Control-Allow-Origin)" = "$APP" ] && has_hdr Location; then
    ok "POST from a listed origin: 201 with Allow-Origin (Location exposed)"
else
    not_ok "a listed POST" "code $c" "$(cat "$WORK/b")"
fi
own=${BASE#http://}
c=$(req POST "$BASE/v1/jobs" -H "Origin: $BASE" "${form[@]}")
check "POST from the daemon's own origin (Origin matches Host $own): 201" [ "$c" = 201 ]
# DNS rebinding: the attacker's name resolves to the daemon, so the
# browser sends that name in both Host and Origin (issue 28; before: 201)
port=${BASE##*:}
c=$(req POST "$BASE/v1/jobs" -H "Host: attacker.example.test:$port" \
    -H "Origin: http://attacker.example.test:$port" "${form[@]}")
check "DNS rebinding: POST whose Host and Origin name the attacker: 421 (the Host check, before the Origin's 403)" [ "$c" = 421 ]
c=$(req POST "$BASE/v1/jobs" "${form[@]}")
B=$(jq -r '.jobID // empty' "$WORK/b")
check "POST without Origin (curl, the client): 201" [ "$c" = 201 ]
c=$(req DELETE "$BASE/v1/jobs/$B" -H 'Origin: http://evil.example.test')
if [ "$c" = 403 ] && [ "$(job_state "$B")" != 404 ]; then
    ok "DELETE from a foreign origin: 403, the job stays"
else
    not_ok "a foreign DELETE" "code $c" "$(cat "$WORK/b")"
fi
c=$(req GET "$BASE/v1/jobs/$B" -H 'Origin: http://evil.example.test')
check "GET from a foreign origin still answers (the browser withholds it)" [ "$c" = 200 ]
wait_final "$A" 60
# browser security headers on the page, a script, JSON and a download
# (issue 28: none before)
bad=""
for u in / /app/app.js /v1/jobs "/v1/jobs/$A/results/mesh" /nothing; do
    c=$(req GET "$BASE$u")
    [ "$(hdr X-Content-Type-Options)" = nosniff ] && [ "$(hdr X-Frame-Options)" = DENY ] &&
        [ "$(hdr Content-Security-Policy)" = "frame-ancestors 'none'" ] &&
        [ "$(hdr Referrer-Policy)" = no-referrer ] || bad="$bad [$u $c]"
done
check "nosniff, frame policy and Referrer-Policy on HTML, script, JSON, download and 404${bad:+:$bad}" \
    test -z "$bad"
stop_daemon

# ------------------------------------------------ behind a reverse proxy
PUB=https://shapematch.example.test
start_daemon proxy --workers 1 --public-url "$PUB/prefix" || { not_ok "the daemon starts with --public-url"; exit 1; }
c=$(req POST "$BASE/v1/jobs" -H "Origin: $PUB" -H 'Host: 10.0.0.5:8080' "${form[@]}")
check "--public-url: POST from its origin (the proxy's Host an address) is the daemon's own: 201" [ "$c" = 201 ]
c=$(req POST "$BASE/v1/jobs" -H "Origin: $PUB" -H 'Host: shapematch.example.test' "${form[@]}")
c2=$(req POST "$BASE/v1/jobs" -H "Origin: $PUB" -H 'Host: internal:8080' "${form[@]}")
check "--public-url: the proxy passing the public Host 201, an upstream name not listed with --allowed-host 421 ($c $c2)" \
    test "$c" = 201 -a "$c2" = 421
c=$(req POST "$BASE/v1/jobs" -H "Origin: https://else.example.test" "${form[@]}")
check "--public-url: POST from another origin: 403" [ "$c" = 403 ]
stop_daemon

# ------------------------------------------------ a Host allow-list
start_daemon named --workers 1 --allowed-host maps.example.test || { not_ok "the daemon starts with --allowed-host"; exit 1; }
port=${BASE##*:}
c=$(req GET "$BASE/v1/jobs" -H "Host: attacker.example.test:$port")
c2=$(req GET "$BASE/v1/jobs" -H "Host: maps.example.test:$port")
c3=$(req GET "$BASE/v1/jobs")
c4=$(req POST "$BASE/v1/jobs" -H "Host: maps.example.test:$port" -H "Origin: http://maps.example.test:$port" "${form[@]}")
check "--allowed-host: Host attacker 421, the allowed name 200, an address 200, POST from the allowed name's origin 201 ($c $c2 $c3 $c4)" \
    test "$c" = 421 -a "$c2" = 200 -a "$c3" = 200 -a "$c4" = 201
stop_daemon

# --------------------------------------------------------- configuration
printf 'sekrit-token-4f2a\n' >"$WORK/tokens"
if ! "$BIN/shapematchd" --tokens-file "$WORK/tokens" --cors-origin '*' --spool "$WORK/x" 2>"$WORK/star.err" &&
    grep -q "'\*' is refused with --tokens-file" "$WORK/star.err"; then
    ok "--cors-origin '*' with --tokens-file is refused at start"
else
    not_ok "'*' with tokens" "$(cat "$WORK/star.err")"
fi
if ! "$BIN/shapematchd" --cors-origin 'https://a.example/path' --spool "$WORK/x" 2>"$WORK/bad.err" &&
    grep -q "is not an origin" "$WORK/bad.err"; then
    ok "an origin with a path is refused at start"
else
    not_ok "a bad origin" "$(cat "$WORK/bad.err")"
fi
SHAPEMATCH_CORS_ORIGINS="http://one.example.test, $APP" start_daemon env --workers 1 ||
    { not_ok "the daemon starts with SHAPEMATCH_CORS_ORIGINS"; exit 1; }
c=$(req GET "$BASE/healthz" -H "Origin: $APP")
ok1=$([ "$c" = 200 ] && [ "$(hdr Access-Control-Allow-Origin)" = "$APP" ] && echo y)
c=$(req GET "$BASE/healthz" -H "Origin: http://one.example.test")
[ "$c" = 200 ] && [ "$(hdr Access-Control-Allow-Origin)" = http://one.example.test ] && ok2=y || ok2=
check "SHAPEMATCH_CORS_ORIGINS: a comma-separated list" [ "$ok1$ok2" = yy ]
stop_daemon
start_daemon star --workers 1 --cors-origin '*' || { not_ok "the daemon starts with '*'"; exit 1; }
c=$(req GET "$BASE/v1/processes" -H "Origin: http://any.example.test")
check "'*' without tokens: Access-Control-Allow-Origin: *" [ "$c:$(hdr Access-Control-Allow-Origin)" = '200:*' ]
stop_daemon

# ------------------------------------------- tokens: access_token, 403
TOKEN=sekrit-token-4f2a
start_daemon auth --workers 1 --tokens-file "$WORK/tokens" --cors-origin "$APP" --log-level debug ||
    { not_ok "the daemon starts with tokens"; exit 1; }
c=$(req OPTIONS "$BASE/v1/jobs" -H "Origin: $APP" -H 'Access-Control-Request-Method: POST')
check "with tokens, a preflight needs none: 204" [ "$c" = 204 ]
c=$(req POST "$BASE/v1/jobs" -H "Origin: http://evil.example.test" -H "Authorization: Bearer $TOKEN" "${form[@]}")
check "with tokens, a foreign POST with a good token: 403" [ "$c" = 403 ]
AUTH=(-H "Authorization: Bearer $TOKEN")
A=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 8)" -H "Origin: $APP")
if [ -n "$A" ] && wait_final "$A" 60 && state_is "$A" successful; then
    ok "a listed origin submits with Authorization and the job completes"
else
    not_ok "a token job" "$(cat "$WORK/submit.out")"
fi
AUTH=()
c=$(req GET "$BASE/v1/jobs/$A/events?access_token=$TOKEN" -H 'Accept: text/event-stream' -H "Origin: $APP")
if [ "$c" = 200 ] && grep -q '^event: ' "$WORK/b" && [ "$(hdr Access-Control-Allow-Origin)" = "$APP" ]; then
    ok "events with ?access_token= (EventSource): 200 and the stream, CORS headers"
else
    not_ok "events with access_token" "code $c" "$(head -c 500 "$WORK/b")"
fi
c=$(req GET "$BASE/v1/jobs/$A/results/mesh?format=vtu&access_token=$TOKEN")
if [ "$c" = 200 ] && grep -q VTKFile "$WORK/b"; then
    ok "a download link with ?access_token=: 200 and the VTU file"
else
    not_ok "a download with access_token" "code $c" "$(head -c 300 "$WORK/b")"
fi
c=$(req GET "$BASE/v1/jobs/$A/events?access_token=wrong")
check "a wrong access_token: 401" [ "$c" = 401 ]
c=$(req DELETE "$BASE/v1/jobs/$A?access_token=$TOKEN")
AUTH=(-H "Authorization: Bearer $TOKEN")
still=$(job_state "$A")
AUTH=()
if [ "$c" = 401 ] && [ "$still" = successful ]; then
    ok "access_token is not accepted on DELETE (GET routes only): 401"
else
    not_ok "access_token on DELETE" "code $c"
fi
c=$(req GET "$BASE/metrics" -H "Authorization: Bearer $TOKEN")
cp "$WORK/b" "$WORK/metrics.txt"
stop_daemon
if ! grep -q "$TOKEN" "$DLOG" "$WORK/metrics.txt" && grep -q '"route":"/v1/jobs/{id}/events"' "$DLOG"; then
    ok "the token appears neither in the daemon's log (requests logged) nor in /metrics"
else
    not_ok "the token leaked" "$(grep -n "$TOKEN" "$DLOG" "$WORK/metrics.txt" | head -5)"
fi
check "no sanitizer reports" reports_clean
echo "1..$n"
