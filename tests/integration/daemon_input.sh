#!/usr/bin/env bash
# shapematchd against bad requests: malformed and truncated multipart
# bodies, wrong, missing and repeated part names, wrong media types,
# unparsable meshes, mismatched dimensions, a distance of the wrong size,
# garbage and invalid params, an empty clamp set, oversize bodies (with and
# without Content-Length), clients that vanish mid-upload, slow-loris
# style partial requests and the per-address connection limit.  Each gets
# the right 4xx with a clear message (or a closed connection), nothing is
# queued or left behind, and the daemon keeps serving.
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
ok "gmsh builds the test meshes"
# a distance field sampled on the template instead of the background
awk -v R=0.8 -f "$WORK/case/sdf.awk" "$DISK" >"$WORK/case/disk.sol"
printf 'this is not a mesh\n' >"$WORK/case/garbage.mesh"

start_daemon input --workers 1 --max-upload 300K --connection-timeout 2 --max-connections-per-ip 12 ||
    { not_ok "daemon starts"; exit 1; }
ok "the daemon starts (--max-upload 300K --connection-timeout 2 --max-connections-per-ip 12)"
GOOD=$(quick_params 5)

# expect_problem DESC CODE DETAIL-REGEX CURL-ARGS...: POST /v1/jobs
expect_problem() {
    local desc=$1 want=$2 re=$3
    shift 3
    local got
    got=$(curl -sS --max-time $((20 * SLOW)) -o "$WORK/p.json" -w '%{http_code} %{content_type}' "$@" \
        "$BASE/v1/jobs" 2>"$WORK/p.err")
    if [ "$got" = "$want application/problem+json" ] &&
        jq -e --argjson s "$want" --arg re "$re" '.status == $s and (.detail | test($re)) and (.title | length > 0)' \
            "$WORK/p.json" >/dev/null; then
        ok "$desc: $want \"$(jq -r .detail "$WORK/p.json" | head -c 150)\""
    else
        not_ok "$desc" "got $got" "$(cat "$WORK/p.json" "$WORK/p.err" 2>/dev/null | head -c 600)"
    fi
    curl -sS --max-time 5 "$BASE/healthz" >/dev/null || not_ok "the daemon still answers after: $desc"
}
F=(-F "template=@$DISK" -F "target_mesh=@$BOX" -F "target_sol=@$BOXSOL")

expect_problem "missing part" 400 'missing part "params"' "${F[@]}"
expect_problem "unknown part name" 400 'unknown part "mesh"' -F "mesh=@$DISK" -F "target_mesh=@$BOX" \
    -F "target_sol=@$BOXSOL" -F "params=$GOOD"
expect_problem "a part given twice" 400 'more than once' "${F[@]}" -F "template=@$DISK" -F "params=$GOOD"
expect_problem "JSON instead of multipart" 415 'multipart/form-data' -H 'Content-Type: application/json' \
    -d '{"clamp": {"kind": "none"}}'
expect_problem "a urlencoded form" 415 'multipart/form-data' -d 'template=x'
expect_problem "multipart without a boundary" 400 'boundary' -H 'Content-Type: multipart/form-data' \
    --data-binary 'hello'
expect_problem "a body that is not multipart" 400 'malformed|truncated|missing part' \
    -H 'Content-Type: multipart/form-data; boundary=XyZ' --data-binary 'garbage, no boundary in sight'
# a well-formed start cut before the closing boundary
{
    printf -- '--XyZ\r\nContent-Disposition: form-data; name="template"; filename="t.mesh"\r\n\r\n'
    head -c 5000 "$DISK"
} >"$WORK/truncated.body"
expect_problem "a truncated multipart body" 400 'truncated|malformed|missing part' \
    -H 'Content-Type: multipart/form-data; boundary=XyZ' --data-binary "@$WORK/truncated.body"
expect_problem "Idempotency-Key with a space" 400 'Idempotency-Key' -H 'Idempotency-Key: a b' "${F[@]}" -F "params=$GOOD"

expect_problem "a template that is not a mesh" 422 '^template: ' -F "template=@$WORK/case/garbage.mesh" \
    -F "target_mesh=@$BOX" -F "target_sol=@$BOXSOL" -F "params=$GOOD"
expect_problem "a 2D template with a 3D target" 422 'dimension mismatch' -F "template=@$DISK" \
    -F "target_mesh=@$CUBE" -F "target_sol=@$CUBESOL" -F "params=$GOOD"
expect_problem "a distance of the wrong size" 422 '^target_sol: has [0-9]+ values but the target mesh has [0-9]+ vertices' \
    -F "template=@$DISK" -F "target_mesh=@$BOX" -F "target_sol=@$WORK/case/disk.sol" -F "params=$GOOD"
expect_problem "a mesh given as the distance" 422 '^target_sol: ' -F "template=@$DISK" -F "target_mesh=@$BOX" \
    -F "target_sol=@$BOX" -F "params=$GOOD"
expect_problem "garbage JSON params" 422 '^params' "${F[@]}" -F 'params={"clamp": {'
expect_problem "params not an object" 422 '^params' "${F[@]}" -F 'params=[1, 2]'
expect_problem "an unknown parameter" 422 'params\.bogus' "${F[@]}" \
    -F 'params={"clamp": {"kind": "none"}, "bogus": 1}'
expect_problem "a parameter of the wrong type" 422 'params\.clamp\.radius' "${F[@]}" \
    -F 'params={"clamp": {"kind": "ball", "center": [0, 0], "radius": "big"}}'
expect_problem "a parameter out of range" 422 'params\.poisson' "${F[@]}" \
    -F 'params={"clamp": {"kind": "none"}, "poisson": 0.5}'
expect_problem "an empty clamp set" 422 'clamp set is empty' "${F[@]}" \
    -F 'params={"clamp": {"kind": "ball", "center": [5, 5], "radius": 0.01}}'
expect_problem "clamp references that match nothing" 422 'params\.clamp\.refs: the clamp set is empty' "${F[@]}" \
    -F 'params={"clamp": {"kind": "vertices", "refs": [987]}}'
if jq -e '."invalid-params"[0].name == "params.clamp.refs"' "$WORK/p.json" >/dev/null; then
    ok "422 problems carry invalid-params naming the field"
else
    not_ok "invalid-params" "$(cat "$WORK/p.json")"
fi

# oversize: with Content-Length (refused before the body), and chunked
big=$WORK/big.bin
head -c 1500000 /dev/urandom >"$big"
expect_problem "a body over --max-upload (Content-Length)" 413 'limit of 307200 bytes' -F "template=@$big" \
    -F "target_mesh=@$BOX" -F "target_sol=@$BOXSOL" -F "params=$GOOD"
expect_problem "a chunked body over --max-upload" 413 'limit of 307200 bytes' -H 'Transfer-Encoding: chunked' \
    -F "template=@$big" -F "target_mesh=@$BOX" -F "target_sol=@$BOXSOL" -F "params=$GOOD"

# gzip'ed inputs are fine
gzip -c "$DISK" >"$WORK/case/disk.mesh.gz"
gzip -c "$BOXSOL" >"$WORK/case/box.sol.gz"
G=$(submit "$WORK/case/disk.mesh.gz" "$BOX" "$WORK/case/box.sol.gz" "$GOOD")
if [ "$(cat "$WORK/submit.code")" = 201 ] && wait_state "$G" successful 30; then
    ok "gzip-compressed inputs are accepted and the job succeeds"
else
    not_ok "gzip inputs" "$(cat "$WORK/submit.code")" "$(cat "$WORK/submit.out")"
fi

# a client that vanishes in the middle of its upload
port=${BASE##*:}
exec {sock}<>"/dev/tcp/127.0.0.1/$port"
printf 'POST /v1/jobs HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: multipart/form-data; boundary=XyZ\r\nContent-Length: 200000\r\n\r\n' >&$sock
head -c 3000 "$WORK/truncated.body" >&$sock
sleep 0.3
exec {sock}>&-
tmp_empty() { [ -z "$(ls -A "$SPOOL/tmp")" ]; }
if poll 10 tmp_empty && curl -sS --max-time 5 "$BASE/healthz" >/dev/null; then
    ok "a client gone mid-upload leaves nothing in the spool and the daemon serves on"
else
    not_ok "client gone mid-upload" "$(ls "$SPOOL/tmp")"
fi

# slow loris: half-sent requests are closed after --connection-timeout
fds=()
for i in 1 2 3 4 5 6; do
    exec {s}<>"/dev/tcp/127.0.0.1/$port"
    printf 'GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: ' >&$s
    fds+=("$s")
done
t0=$(date +%s.%N)
code=$(curl -sS --max-time 5 -o /dev/null -w '%{http_code}' "$BASE/healthz")
t1=$(date +%s.%N)
fast=$(awk -v a="$t0" -v b="$t1" 'BEGIN { print (b - a < 1.0) ? 1 : 0 }')
if [ "$code" = 200 ] && [ "$fast" = 1 ]; then
    ok "six half-sent requests do not slow /healthz down"
else
    not_ok "healthz with slow clients" "code $code"
fi
closed=0
for s in "${fds[@]}"; do
    # the server closes: reading gives EOF well before our own 8 s bound
    if timeout $((8 * SLOW)) cat <&$s >/dev/null 2>&1; then closed=$((closed + 1)); fi
    exec {s}>&-
done
if [ "$closed" = 6 ]; then
    ok "the half-sent requests are closed by the server after --connection-timeout"
else
    not_ok "slow-loris connections closed" "closed $closed of 6"
fi

# the per-address limit: 12 idle connections fill it, the 13th is refused
fds=()
for i in $(seq 1 12); do
    exec {s}<>"/dev/tcp/127.0.0.1/$port"
    fds+=("$s")
done
sleep 0.3
code=$(curl -sS --max-time 3 -o /dev/null -w '%{http_code}' "$BASE/healthz" 2>/dev/null)
for s in "${fds[@]}"; do exec {s}>&-; done
healthy() { [ "$(curl -sS --max-time 3 -o /dev/null -w '%{http_code}' "$BASE/healthz")" = 200 ]; }
if [ "$code" != 200 ] && poll 10 healthy; then
    ok "--max-connections-per-ip 12: a 13th connection is refused (got '$code'), served again once they close"
else
    not_ok "per-address connection limit" "13th got $code"
fi

lst=$(curl -sS "$BASE/v1/jobs")
if [ "$(printf '%s' "$lst" | jq .numberMatched)" = 1 ]; then
    ok "only the one valid submission became a job"
else
    not_ok "no job from bad requests" "$(printf '%s' "$lst" | jq -c '[.jobs[].jobID]')"
fi
if tmp_empty; then ok "no upload left in the spool's tmp/"; else not_ok "tmp/ is empty" "$(ls "$SPOOL/tmp")"; fi
stop_daemon
rc=$?
[ "$rc" = 0 ] && ok "SIGTERM: exit 0" || not_ok "SIGTERM: exit 0" "status $rc" "$(tail -3 "$DLOG")"
if reports_clean; then ok "no sanitizer report in the daemon or worker logs"; else not_ok "sanitizer reports" "$(grep -lE 'Sanitizer|runtime error' "$WORK"/*.log 2>/dev/null)"; fi
echo "1..$n"
