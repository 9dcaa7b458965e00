#!/usr/bin/env bash
# shapematchd's HTTP strictness and upload checks (issue 8): a repeated
# Content-Length (ambiguous framing), an HTTP/1.1 request without Host and
# a repeated Authorization header answer 400 problem+json; templates the
# solver cannot handle — a bowtie (two triangles sharing one vertex only)
# or a part the clamp does not hold — answer 422 at upload, nothing is
# queued, and `shapematch run` refuses the same inputs (shared checks).
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
ok "gmsh builds the test meshes"

start_daemon strict --workers 1 || { not_ok "the daemon starts"; exit 1; }
ok "the daemon starts"
PORT=${BASE##*:}

# raw REQUEST: sends the bytes as they are, prints the reply (at most 3 s)
raw() {
    python3 - "$PORT" "$1" <<'EOF'
import socket, sys
s = socket.create_connection(("127.0.0.1", int(sys.argv[1])), timeout=3)
s.sendall(sys.argv[2].encode().decode("unicode_escape").encode("latin-1"))
out = b""
try:
    while True:
        b = s.recv(65536)
        if not b:
            break
        out += b
except socket.timeout:
    pass
sys.stdout.write(out.decode("latin-1"))
EOF
}
# expect_400 DESC REQUEST DETAIL-REGEX
expect_400() {
    local out
    out=$(raw "$2")
    if grep -q '^HTTP/1.1 400' <<<"$out" && grep -qi '^Content-Type: application/problem+json' <<<"$out" &&
        sed -n '/^{/,$p' <<<"$out" | jq -e --arg re "$3" '.status == 400 and (.detail | test($re))' >/dev/null; then
        ok "$1: 400 \"$(sed -n '/^{/,$p' <<<"$out" | jq -r .detail)\""
    else
        not_ok "$1: 400" "$(head -c 600 <<<"$out")"
    fi
}
expect_400 "Content-Length twice (equal)" \
    'GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 0\r\nContent-Length: 0\r\n\r\n' '^Content-Length:'
expect_400 "Content-Length twice (different)" \
    'POST /v1/jobs HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 1\r\nContent-Length: 0\r\n\r\nx' '^Content-Length:'
expect_400 "HTTP/1.1 without Host" 'GET /healthz HTTP/1.1\r\n\r\n' '^Host:'
expect_400 "Authorization twice (identical)" \
    'GET /v1/jobs HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer a\r\nAuthorization: Bearer a\r\n\r\n' '^Authorization:'
# a transfer coding other than chunked got no answer at all (issue 28)
out=$(raw 'GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nTransfer-Encoding: gzip, chunked\r\n\r\n')
if grep -q '^HTTP/1.1 501' <<<"$out" && grep -q 'only chunked' <<<"$out"; then
    ok "Transfer-Encoding: gzip, chunked: 501 naming the coding"
else
    not_ok "Transfer-Encoding other than chunked: 501" "$(head -c 400 <<<"$out")"
fi
if grep -q '^HTTP/1.1 200' <<<"$(raw 'GET /healthz HTTP/1.0\r\n\r\n')" &&
    grep -q '^HTTP/1.1 200' <<<"$(raw 'GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n')"; then
    ok "HTTP/1.0 without Host and HTTP/1.1 with one are served"
else
    not_ok "well-formed requests are served"
fi

# a bowtie: two triangles that share vertex 1 only
cat >"$WORK/bowtie.mesh" <<'EOF'
MeshVersionFormatted 2
Dimension 2
Vertices
5
0 0 0
0.4 0 0
0 0.4 0
-0.4 0 0
0 -0.4 0
Triangles
2
1 2 3 0
1 4 5 0
End
EOF
# two squares, the clamp ball holds the first one only
cat >"$WORK/two.mesh" <<'EOF'
MeshVersionFormatted 2
Dimension 2
Vertices
8
-0.5 -0.2 0
-0.1 -0.2 0
-0.1 0.2 0
-0.5 0.2 0
0.1 -0.2 0
0.5 -0.2 0
0.5 0.2 0
0.1 0.2 0
Triangles
4
1 2 3 0
1 3 4 0
5 6 7 0
5 7 8 0
End
EOF
TWO_PARAMS='{"clamp": {"kind": "ball", "center": [-0.3, -0.2], "radius": 0.25}, "max_iter": 5}'
ALL_PARAMS='{"clamp": {"kind": "ball", "center": [0, -0.2], "radius": 0.45}, "max_iter": 5}'

# expect_422 DESC TEMPLATE PARAMS DETAIL-REGEX
expect_422() {
    local before after code
    before=$(ls "$SPOOL/jobs" 2>/dev/null | wc -l)
    submit "$2" "$BOX" "$BOXSOL" "$3" >/dev/null
    code=$(cat "$WORK/submit.code")
    after=$(ls "$SPOOL/jobs" 2>/dev/null | wc -l)
    if [ "$code" = 422 ] && [ "$before" = "$after" ] &&
        jq -e --arg re "$4" '.status == 422 and (.detail | test($re))' "$WORK/submit.out" >/dev/null; then
        ok "$1: 422 at upload, nothing queued: \"$(jq -r .detail "$WORK/submit.out")\""
    else
        not_ok "$1: 422" "code $code, jobs $before -> $after" "$(cat "$WORK/submit.out")"
    fi
}
expect_422 "a bowtie template" "$WORK/bowtie.mesh" "$(quick_params 5)" '^template: vertex 1 is non-manifold'
expect_422 "a second part the clamp does not hold" "$WORK/two.mesh" "$TWO_PARAMS" \
    '^params.clamp: the template has 2 separate parts .* not clamped'
id=$(submit "$WORK/two.mesh" "$BOX" "$BOXSOL" "$ALL_PARAMS")
if [ "$(cat "$WORK/submit.code")" = 201 ] && [ -n "$id" ]; then
    ok "two parts both held by the clamp: 201"
else
    not_ok "two parts both held: 201" "$(cat "$WORK/submit.out")"
fi

# the same inputs through `shapematch run`: refused before any step
run_refuses() {
    "$BIN/shapematch" run --template "$2" --target-mesh "$BOX" --target-sol "$BOXSOL" $3 --max-iter 5 \
        -o "$WORK/run-out" >"$WORK/run.out" 2>&1
    local rc=$?
    if { [ "$rc" = 1 ] || [ "$rc" = 2 ]; } && grep -qE "$4" "$WORK/run.out"; then
        ok "shapematch run refuses $1 (exit $rc): $(head -1 "$WORK/run.out")"
    else
        not_ok "shapematch run refuses $1" "exit $rc" "$(cat "$WORK/run.out")"
    fi
}
run_refuses "a bowtie" "$WORK/bowtie.mesh" "--clamp-ball 0,0,0.1" 'vertex 1 is non-manifold'
run_refuses "an unclamped part" "$WORK/two.mesh" "--clamp-ball -0.3,-0.2,0.25" '2 separate parts'

if stop_daemon && reports_clean; then
    ok "SIGTERM stops the daemon, no sanitizer report"
else
    not_ok "clean stop"
fi
echo "1..$n"
