#!/usr/bin/env bash
# Tenants (issue 8): a tokens file with "TOKEN NAME [admin]" lines; a job
# belongs to the submitting token's tenant; another tenant gets 404 on
# every route of it (walked from the route table: status, events, live
# mesh, results, snapshots, cancel and delete) and does not see it in the
# list, nor a batch of it (the batch routes, walked alike); an admin sees every job; an Idempotency-Key is scoped to its
# tenant; SIGHUP reloads the tokens (logged), a broken file keeps the old
# ones.
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
ok "gmsh builds the test meshes"
TOKENS=$WORK/tokens
printf '# tenants\ntok-alice alice\ntok-bob bob\ntok-ops ops admin\n' >"$TOKENS"
start_daemon ten --workers 1 --tokens-file "$TOKENS" || { not_ok "the daemon starts"; exit 1; }
ok "the daemon starts with a tenants file"

as() { AUTH=(-H "Authorization: Bearer tok-$1"); }
code_as() { # TENANT METHOD URL: the HTTP status
    curl -sS --max-time $((10 * SLOW)) -o "$WORK/reply.json" -w '%{http_code}' \
        -H "Authorization: Bearer tok-$1" -X "$2" "$3" "${@:4}"
}
as alice
A=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)")
as bob
B=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)")
if [ -n "$A" ] && [ -n "$B" ] && as alice && wait_final "$A" 60 && as bob && wait_final "$B" 60; then
    ok "alice and bob each submit a job"
else
    not_ok "two tenants submit" "$(cat "$WORK/submit.out")"
fi

# every route of a job, read from the route table itself (a new route is
# walked too): bob gets 404 no-such-job for alice's job, as if it did not
# exist; alice does not (DELETE last, so that her job stays meanwhile)
routes=$(sed -n 's/^ *{SMD_METHOD_\([A-Z]*\), *\(JOB\|RESULTS\)\( "[^"]*"\)\{0,1\},.*/\1 \2\3/p' \
    "$ROOT/server/api/smd_route_table.c" | tr -d '"' | sort -k1,1r)
walked=0 bad=""
while read -r method base suffix; do
    case $method in READ) method=GET ;; esac
    path=/v1/jobs/$A
    [ "$base" = RESULTS ] && path=$path/results
    path=$path${suffix//\{iteration\}/1}
    c=$(code_as bob "$method" "$BASE$path")
    jq -e '.status == 404 and (.type | test("no-such-job"))' "$WORK/reply.json" >/dev/null 2>&1 ||
        bad="$bad [bob $method $path: $c $(head -c 120 "$WORK/reply.json")]"
    if [ "$method" != DELETE ]; then
        code_as alice "$method" "$BASE$path" >/dev/null
        ! grep -q no-such-job "$WORK/reply.json" || bad="$bad [alice $method $path: no-such-job]"
    fi
    walked=$((walked + 1))
done <<<"$routes"
if [ "$walked" -ge 10 ] && [ -z "$bad" ]; then
    ok "bob gets 404 no-such-job on each of the $walked job routes of the route table for alice's job"
else
    not_ok "every job route hides another tenant's job" "walked $walked:$bad"
fi
ids() { jq -r '[.jobs[].jobID] | sort | join(" ")' "$WORK/reply.json"; }
# access_token (the browsers' form of the token) names the tenant too
tok_code() { # TOKEN URL: the HTTP status, the token in the query only
    curl -sS --max-time $((10 * SLOW)) -o "$WORK/reply.json" -w '%{http_code}' "$2?access_token=$1"
}
if [ "$(tok_code tok-bob "$BASE/v1/jobs/$A")" = 404 ] && [ "$(tok_code tok-alice "$BASE/v1/jobs/$A")" = 200 ] &&
    tok_code tok-bob "$BASE/v1/jobs" >/dev/null && [ "$(ids)" = "$B" ]; then
    ok "access_token: bob's token in the query sees his job only, alice's sees hers"
else
    not_ok "access_token is scoped to its tenant" "$(head -c 300 "$WORK/reply.json")"
fi
code_as bob GET "$BASE/v1/jobs" >/dev/null
if [ "$(ids)" = "$B" ]; then ok "bob's list holds his job only"; else not_ok "bob's list" "$(ids)"; fi
code_as alice GET "$BASE/v1/jobs" >/dev/null
if [ "$(ids)" = "$A" ]; then ok "alice's list holds her job only"; else not_ok "alice's list" "$(ids)"; fi
code_as ops GET "$BASE/v1/jobs" >/dev/null
if [ "$(ids)" = "$(printf '%s\n' "$A" "$B" | sort | tr '\n' ' ' | sed 's/ $//')" ] &&
    [ "$(code_as ops GET "$BASE/v1/jobs/$A")" = 200 ] && [ "$(code_as ops GET "$BASE/v1/jobs/$B/results")" = 200 ]; then
    ok "the admin sees both jobs and their results"
else
    not_ok "the admin sees every job" "$(ids)"
fi
if [ "$(code_as alice GET "$BASE/v1/jobs/$A")" = 200 ] && jq -e '.status == "successful"' "$WORK/reply.json" >/dev/null; then
    ok "alice still has her job (bob's DELETE changed nothing)"
else
    not_ok "alice's job survived bob's DELETE" "$(cat "$WORK/reply.json")"
fi

# Idempotency-Key per tenant
as alice
K1=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)" -H 'Idempotency-Key: same-key')
as bob
K2=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)" -H 'Idempotency-Key: same-key')
as alice
K3=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)" -H 'Idempotency-Key: same-key')
if [ -n "$K1" ] && [ -n "$K2" ] && [ "$K1" != "$K2" ] && [ "$K1" = "$K3" ]; then
    ok "an Idempotency-Key is scoped to its tenant (bob's gets a job of his own, alice's retry hers)"
else
    not_ok "Idempotency-Key per tenant" "$K1 / $K2 / $K3"
fi

# SIGHUP: bob's token goes, carol's comes.  Bob follows a job of his (his
# token in the header) and ops the same job (its token as access_token):
# the reload ends bob's stream, ops's stays open.
as bob
E=$(submit "$DISK" "$BOX" "$BOXSOL" "$(endless_params)")
poll 20 state_is "$E" running
curl -sS -N --max-time 30 -H 'Authorization: Bearer tok-bob' "$BASE/v1/jobs/$E/events" \
    >"$WORK/bob.ndjson" 2>/dev/null &
BOBS=$!
curl -sS -N --max-time 30 "$BASE/v1/jobs/$E/events?access_token=tok-ops" >"$WORK/ops.ndjson" 2>/dev/null &
OPSS=$!
streaming() { [ -s "$WORK/bob.ndjson" ] && [ -s "$WORK/ops.ndjson" ]; }
poll 10 streaming
printf 'tok-alice alice\ntok-carol carol\ntok-ops ops admin\n' >"$TOKENS"
kill -HUP "$DPID"
reloaded() { [ "$(grep -c '"event":"tokens_reloaded"' "$DLOG")" -ge "$1" ]; }
gone() { ! kill -0 "$1" 2>/dev/null; }
if poll 10 gone "$BOBS" && kill -0 "$OPSS" 2>/dev/null; then
    ok "SIGHUP that removes a token ends the event streams opened with it (bob's), not the others (ops's)"
else
    not_ok "revocation closes the token's streams" "bob's stream $(gone "$BOBS" && echo ended || echo open)," \
        "ops's $(gone "$OPSS" && echo ended || echo open)"
fi
curl -sS -o /dev/null -H 'Authorization: Bearer tok-ops' -X DELETE "$BASE/v1/jobs/$E"
kill "$BOBS" "$OPSS" 2>/dev/null
wait "$BOBS" "$OPSS" 2>/dev/null
if poll 10 reloaded 1 && [ "$(code_as carol GET "$BASE/v1/jobs")" = 200 ] && [ "$(ids)" = "" ] &&
    [ "$(code_as bob GET "$BASE/v1/jobs")" = 401 ] && [ "$(code_as alice GET "$BASE/v1/jobs/$A")" = 200 ]; then
    ok "SIGHUP reloads the tokens (logged): carol is in, bob is out, alice keeps her jobs"
else
    not_ok "SIGHUP reloads the tokens" "$(grep -E 'reload|tokens' "$DLOG" | tail -3)"
fi
printf 'tok-x one two three\n' >"$TOKENS"
kill -HUP "$DPID"
broken() { grep -q '"event":"reload".*kept' "$DLOG"; }
if poll 10 broken && [ "$(code_as carol GET "$BASE/v1/jobs")" = 200 ]; then
    ok "a broken tokens file on SIGHUP is refused (logged), the tokens in use stay"
else
    not_ok "a broken tokens file keeps the old tokens" "$(grep reload "$DLOG" | tail -2)"
fi

# the batch routes alike (GET, events, model, DELETE): alice's batch of
# her job is 404 to carol (bob's token is gone by now), not to her
code_as alice POST "$BASE/v1/batches" -H 'Content-Type: application/json' \
    --data-binary "{\"targets\": [{\"job\": \"$A\", \"name\": \"a\"}]}" >/dev/null
AB=$(jq -r '.batchID // empty' "$WORK/reply.json")
batch_final() { code_as alice GET "$BASE/v1/batches/$AB" >/dev/null; jq -e '.status | test("successful|failed|dismissed")' "$WORK/reply.json" >/dev/null; }
poll 30 batch_final
routes=$(sed -n 's/^ *{SMD_METHOD_\([A-Z]*\), *BATCH\( "[^"]*"\)\{0,1\},.*/\1\2/p' \
    "$ROOT/server/api/smd_route_table.c" | tr -d '"' | sort -k1,1r)
walked=0 bad=""
while read -r method suffix; do
    case $method in READ) method=GET ;; esac
    path=/v1/batches/$AB${suffix//\{file\}/mean.mesh}
    c=$(code_as carol "$method" "$BASE$path")
    [ "$c" = 404 ] || bad="$bad [carol $method $path: $c]"
    if [ "$method" != DELETE ]; then
        c=$(code_as alice "$method" "$BASE$path")
        [ "$c" != 404 ] || bad="$bad [alice $method $path: 404]"
    fi
    walked=$((walked + 1))
done <<<"$routes"
if [ -n "$AB" ] && [ "$walked" -ge 5 ] && [ -z "$bad" ]; then
    ok "carol gets 404 on each of the $walked batch routes of the route table for alice's batch"
else
    not_ok "every batch route hides another tenant's batch" "batch $AB, walked $walked:$bad"
fi

if stop_daemon && reports_clean; then
    ok "SIGTERM stops the daemon, no sanitizer report"
else
    not_ok "clean stop"
fi
echo "1..$n"
