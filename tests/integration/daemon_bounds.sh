#!/usr/bin/env bash
# Bounded work for every input (issue 8): the two decompression bombs of
# the issue — a 437 KB .mesh.gz declaring 50 million vertices, and a small
# gzip holding 64 MiB of blanks — are refused with 413 problem+json naming
# the limit (--max-vertices, --max-inflated) within seconds, the daemon's
# peak RSS stays small and /healthz answers meanwhile; --max-elements and
# --max-vertices refuse a declared count before anything is allocated.
# The acceptance check runs in a child process off the HTTP threads: with
# one HTTP thread, /healthz, a status and an event stream answer within
# 0.5 s while a 150 MB (inflated) upload is being checked, the daemon's
# RSS does not grow with it, and --check-timeout stops a check that takes
# too long (422 naming the flag).  A target_surface gzip bomb is refused
# by --max-inflated like a mesh.
# The check cases wait for states, not for time: a check is paused once it
# runs (the release build's check child stopped; the sanitizer build checks
# in a daemon thread, so there the daemon is stopped), so that it is still
# in progress when it must be, on any machine and under any load.
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
ok "gmsh builds the test meshes"
python3 - "$WORK" <<'EOF'
import gzip, sys
w = sys.argv[1]
with gzip.open(w + "/verts.mesh.gz", "wb", compresslevel=9) as f:
    f.write(b"MeshVersionFormatted 2\nDimension 2\nVertices\n50000000\n")
    chunk = b"0 0 0\n" * 1000000
    for i in range(50):
        f.write(chunk)
    f.write(b"Triangles\n1\n1 2 3 0\nEnd\n")
with gzip.open(w + "/blanks.mesh.gz", "wb", compresslevel=9) as f:
    f.write(b"MeshVersionFormatted 2\nDimension 2\n")
    chunk = b" " * (1 << 20)
    for i in range(64):
        f.write(chunk)
    f.write(b"Vertices\n3\n0 0 0\n1 0 0\n0 1 0\nTriangles\n1\n1 2 3 0\nEnd\n")
# a surface bomb: 64 MiB of blanks in front of an OBJ triangle
with gzip.open(w + "/bomb.obj.gz", "wb", compresslevel=9) as f:
    f.write(b"# bomb\n")
    for i in range(64):
        f.write((b" " * 63 + b"\n") * (1 << 14))
    f.write(b"\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
EOF
ok "bombs: $(stat -c %s "$WORK/verts.mesh.gz") bytes (50M vertices), $(stat -c %s "$WORK/blanks.mesh.gz") bytes (64 MiB of blanks)"

start_daemon bounds --workers 1 --max-upload 1M || { not_ok "the daemon starts"; exit 1; }
ok "the daemon starts (--max-upload 1M: --max-inflated 4M, --max-vertices 1M from --memory-limit 4G)"

# bomb DESC FILE FLAG: 413 naming FLAG within seconds, /healthz answering
# during the upload
bomb() {
    local t0 t1 c healthy=0 i
    t0=${EPOCHREALTIME/,/.}
    curl -sS --max-time $((30 * SLOW)) -o "$WORK/bomb.json" -w '%{http_code}' -F "template=@$2" \
        -F "target_mesh=@$BOX" -F "target_sol=@$BOXSOL" -F "params=$(quick_params 5)" \
        "$BASE/v1/jobs" >"$WORK/bomb.code" 2>/dev/null &
    local cpid=$!
    for ((i = 0; i < 3; i++)); do
        [ "$(curl -sS --max-time 5 -o /dev/null -w '%{http_code}' "$BASE/healthz")" = 200 ] && healthy=$((healthy + 1))
    done
    wait "$cpid"
    t1=${EPOCHREALTIME/,/.}
    c=$(cat "$WORK/bomb.code")
    local secs
    secs=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.2f", b - a }')
    if [ "$c" = 413 ] && [ "$healthy" = 3 ] &&
        jq -e --arg f "$3" '.status == 413 and (.detail | contains($f))' "$WORK/bomb.json" >/dev/null &&
        awk -v s="$secs" -v k="$SLOW" 'BEGIN { exit !(s < 10 * k) }'; then
        ok "$1: 413 in $secs s, /healthz answered 3/3: \"$(jq -r .detail "$WORK/bomb.json")\""
    else
        not_ok "$1: 413 naming $3" "code $c in $secs s, healthz $healthy/3" "$(cat "$WORK/bomb.json")"
    fi
}
bomb "50M vertices in 437 KB of gzip" "$WORK/verts.mesh.gz" --max-vertices
bomb "64 MiB of blanks in a small gzip" "$WORK/blanks.mesh.gz" --max-inflated
c=$(hcurl -o "$WORK/sbomb.json" -w '%{http_code}' -F "template=@$DISK" -F "target_surface=@$WORK/bomb.obj.gz" \
    -F "params=$(quick_params 5)" "$BASE/v1/jobs")
if [ "$c" = 413 ] && jq -e '.detail | test("target_surface.*--max-inflated")' "$WORK/sbomb.json" >/dev/null; then
    ok "a target_surface gzip bomb (64 MiB of blanks before an OBJ triangle): 413 \"$(jq -r .detail "$WORK/sbomb.json")\""
else
    not_ok "a target_surface bomb: 413 naming --max-inflated" "$c" "$(cat "$WORK/sbomb.json")"
fi
hwm=$(awk '/^VmHWM/ { print $2 }' "/proc/$DPID/status")
if [ -n "$hwm" ] && [ "$hwm" -lt $((150 * 1024 * SLOW)) ]; then
    ok "the daemon's peak RSS after both bombs: $((hwm / 1024)) MiB"
else
    not_ok "the daemon's peak RSS stays bounded" "VmHWM ${hwm:-?} kB"
fi
id=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)")
if [ -n "$id" ] && wait_final "$id" 60 && state_is "$id" successful; then
    ok "an ordinary job is still accepted and runs"
else
    not_ok "an ordinary job runs" "$(cat "$WORK/submit.out")"
fi
stop_daemon

start_daemon counts --workers 1 --max-elements 20 || { not_ok "the daemon starts"; exit 1; }
submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)" >/dev/null
if [ "$(cat "$WORK/submit.code")" = 413 ] &&
    jq -e '.detail | test("^template: .*(Triangles|Edges) count [0-9]+ exceeds the limit of 20 records.*--max-elements")' \
        "$WORK/submit.out" >/dev/null; then
    ok "--max-elements 20: 413 \"$(jq -r .detail "$WORK/submit.out")\""
else
    not_ok "--max-elements 20: 413" "$(cat "$WORK/submit.code")" "$(cat "$WORK/submit.out")"
fi
# a target_surface counts too: a small template, an OBJ fan of 39 facets
printf 'MeshVersionFormatted 2\nDimension 3\nVertices\n4\n0 0 0 0\n1 0 0 0\n0 1 0 0\n0 0 1 0\nTetrahedra\n1\n1 2 3 4 0\nEnd\n' >"$WORK/tet.mesh"
awk 'BEGIN { print "v 0 0 0"; for (i = 0; i <= 40; i++) printf "v %.6f %.6f 1\n", cos(i / 6.5), sin(i / 6.5)
             for (i = 2; i <= 40; i++) printf "f 1 %d %d\n", i, i + 1 }' >"$WORK/fan.obj"
c=$(hcurl -o "$WORK/fan.json" -w '%{http_code}' -F "template=@$WORK/tet.mesh" -F "target_surface=@$WORK/fan.obj" \
    -F "params=$(quick_params 5)" "$BASE/v1/jobs")
if [ "$c" = 413 ] && jq -e '.detail | test("^target_surface: .*20 facets.*--max-elements")' "$WORK/fan.json" >/dev/null; then
    ok "a target_surface beyond --max-elements 20: 413 \"$(jq -r .detail "$WORK/fan.json")\""
else
    not_ok "a target_surface beyond --max-elements: 413" "$c" "$(cat "$WORK/fan.json")"
fi
stop_daemon

# ---------------------------------------------- checks off the HTTP thread
python3 - "$WORK" <<'PYEOF'
import gzip, sys
w = sys.argv[1]
# 3M vertex lines (150 MB inflated), then a triangle naming a vertex that
# does not exist: the check reads everything, then refuses it (422).  The
# check must take well over --check-timeout 0.2 (below) on any machine:
# the coordinates have 22 digits, more than the reader converts in place
# (sm_number.h), so each goes through strtod, 0.75 s in all here (short
# coordinates took 0.16 s once the reader was made fast).  Too large to
# be inflated whole, the file is streamed through zlib.  It is a gzip of
# several members (the readers take them one after another, as gzip(1)
# does), the million-line member compressed once and written three times.
import zlib
def member(data):
    z = zlib.compressobj(1, zlib.DEFLATED, 31)
    return z.compress(data) + z.flush()
chunk = member(b"0.1234567890123456789012 0.7654321098765432109876 0\n" * 1000000)
with open(w + "/big.mesh.gz", "wb") as f:
    f.write(member(b"MeshVersionFormatted 2\nDimension 2\nVertices\n3000000\n"))
    for i in range(3):
        f.write(chunk)
    f.write(member(b"Triangles\n1\n1 2 99999999 0\nEnd\n"))
PYEOF
start_daemon big --workers 1 --http-threads 1 --max-vertices 4M --max-inflated 1G \
    --max-upload 64M || { not_ok "the daemon starts"; exit 1; }
id=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)")
wait_final "$id" 60
checks_running() {
    curl -sS --max-time 5 "$BASE/metrics" |
        awk '$1 == "shapematch_upload_checks{state=\"running\"}" { print $2 }'
}
t0=${EPOCHREALTIME/,/.}
curl -sS --max-time $((120 * SLOW)) -o "$WORK/big.json" -w '%{http_code}' -F "template=@$WORK/big.mesh.gz" \
    -F "target_mesh=@$BOX" -F "target_sol=@$BOXSOL" -F "params=$(quick_params 5)" \
    "$BASE/v1/jobs" >"$WORK/big.code" 2>/dev/null &
cpid=$!
running() { [ "$(checks_running)" = 1 ]; }
# check_child: the release build's check process (a fork of the daemon;
# a job's worker is shapematch-worker)
check_child() { ps -o pid=,comm= --ppid "$DPID" | awk '$2 == "shapematchd" { print $1; exit }'; }
has_check_child() { [ -n "$(check_child)" ]; }
# pause_check: once the check runs, the release build's check child is
# stopped (kill -CONT "$PAUSED" resumes it); the sanitizer build's check,
# in a daemon thread, runs on
pause_check() {
    PAUSED=
    poll 30 running || return 1
    [ "$VARIANT" = asan ] && return 0
    poll 30 has_check_child && PAUSED=$(check_child) && kill -STOP "$PAUSED"
}
seen=0
pause_check && seen=1
lat=()
for round in 1 2 3; do
    for path in /healthz "/v1/jobs/$id" "/v1/jobs/$id/events"; do
        lat+=("$(curl -sS --max-time 10 -o /dev/null -w '%{http_code}:%{time_total}' "$BASE$path")")
    done
done
still=$(checks_running)
[ -n "$PAUSED" ] && kill -CONT "$PAUSED"
wait "$cpid"
t1=${EPOCHREALTIME/,/.}
secs=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.1f", b - a }')
worst=$(printf '%s\n' "${lat[@]}" | awk -F: '$1 != 200 { bad = 1 } $2 > m { m = $2 } END { print (bad ? "bad" : m) }')
# 2 s (0.5 s once, which a loaded machine's scheduling alone can take):
# with the check paused, a request it blocked would wait for as long as it
# stays paused, so the bound only tells answered from blocked
limit=2
if [ "$seen" = 1 ] && [ "$worst" != bad ] && awk -v w="$worst" -v l="$limit" 'BEGIN { exit !(w < l) }'; then
    ok "while a 150 MB upload is checked (one HTTP thread), /healthz, status and events answer 9/9 within $worst s (< $limit; the check still running after them: ${still:-?})"
else
    not_ok "requests answer during a big upload's check" "check seen $seen, still running after the probes ${still:-?}" "${lat[*]}"
fi
if [ "$(cat "$WORK/big.code")" = 422 ] && jq -e '.detail | test("template: .*(vertex|99999999)")' "$WORK/big.json" >/dev/null; then
    ok "the big upload is refused with 422 after its check ($secs s): \"$(jq -r .detail "$WORK/big.json" | head -c 160)\""
else
    not_ok "the big upload: 422" "$(cat "$WORK/big.code")" "$(cat "$WORK/big.json")"
fi
hwm=$(awk '/^VmHWM/ { print $2 }' "/proc/$DPID/status")
if [ -n "$hwm" ] && [ "$hwm" -lt $((100 * 1024 * SLOW)) ]; then
    ok "the daemon's peak RSS stays at $((hwm / 1024)) MiB (the check's memory is its child's)"
else
    not_ok "the daemon's RSS does not grow with the check" "VmHWM ${hwm:-?} kB"
fi
# SIGTERM while an upload is being checked: the check is stopped, the
# client gets 503, the daemon exits cleanly
curl -sS --max-time $((60 * SLOW)) -o "$WORK/term.json" -w '%{http_code}' -F "template=@$WORK/big.mesh.gz" \
    -F "target_mesh=@$BOX" -F "target_sol=@$BOXSOL" -F "params=$(quick_params 5)" \
    "$BASE/v1/jobs" >"$WORK/term.code" 2>/dev/null &
cpid=$!
pause_check # still in progress when SIGTERM comes (the daemon kills a paused child)
stop_daemon
rc=$?
wait "$cpid"
if [ "$rc" = 0 ] && [ "$(cat "$WORK/term.code")" = 503 ] && jq -e '.detail | contains("shutting down")' "$WORK/term.json" >/dev/null; then
    ok "SIGTERM during a check: the upload gets 503 \"$(jq -r .detail "$WORK/term.json")\", the daemon exits 0"
else
    not_ok "SIGTERM during a check" "daemon rc $rc, upload $(cat "$WORK/term.code")" "$(cat "$WORK/term.json")"
fi
# --check-timeout: the big upload's check paused past it (the release
# build's child, which the daemon must kill at the deadline; in the
# sanitizer build the daemon itself, stopped for the timeout and more, and
# the deadline is applied when the check returns), an ordinary upload
# passing within it.  The timeout is 3 s (scaled): once 0.2 s, which the
# big check had to outlast by itself and which an ordinary upload did not
# meet on a loaded machine (0.3-0.9 s at load 20).
CT=$((3 * SLOW))
start_daemon slowcheck --workers 1 --check-timeout "$CT" --max-vertices 4M --max-inflated 1G ||
    { not_ok "the daemon starts"; exit 1; }
t0=${EPOCHREALTIME/,/.}
hcurl -o "$WORK/slow.json" -w '%{http_code}' -F "template=@$WORK/big.mesh.gz" -F "target_mesh=@$BOX" \
    -F "target_sol=@$BOXSOL" -F "params=$(quick_params 5)" "$BASE/v1/jobs" >"$WORK/slow.code" &
cpid=$!
paused=no
if pause_check; then
    paused=yes
    if [ "$VARIANT" = asan ]; then
        kill -STOP "$DPID" && sleep "$CT.2" && kill -CONT "$DPID"
    fi
fi
wait "$cpid"
t1=${EPOCHREALTIME/,/.}
c=$(cat "$WORK/slow.code")
secs=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.1f", b - a }')
# (on a loaded machine the check may outlast the timeout by itself, before
# it could be paused: the same verdict)
if [ "$c" = 422 ] && jq -e '.detail | contains("--check-timeout")' "$WORK/slow.json" >/dev/null &&
    awk -v s="$secs" -v b=$((CT + 10 * SLOW)) 'BEGIN { exit !(s < b) }'; then
    ok "--check-timeout $CT: a check past it (paused: $paused), 422 in $secs s \"$(jq -r .detail "$WORK/slow.json")\""
else
    not_ok "--check-timeout: 422 naming it" "check paused: $paused; $c in $secs s" "$(cat "$WORK/slow.json")"
fi
id=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)")
if [ -n "$id" ] && wait_final "$id" 60 && state_is "$id" successful; then
    ok "an ordinary upload passes its check within --check-timeout $CT"
else
    not_ok "an ordinary upload within --check-timeout $CT" "$(cat "$WORK/submit.out")"
fi
stop_daemon
if reports_clean; then
    ok "no sanitizer report"
else
    not_ok "no sanitizer report"
fi
echo "1..$n"
