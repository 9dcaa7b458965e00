#!/usr/bin/env bash
# One client cannot starve another (issue 37 items 4 and 5), on loopback
# with several source addresses (curl --interface 127.0.0.N):
# - upload checks: one address floods the two check slots with slow
#   checks (a 130 KB NRRD declaring 512^3 voxels, each check seconds);
#   another address's upload is checked while the flood still waits
#   (before: behind all of it, first come first served); a check that
#   waited a whole --check-timeout is answered 503 with Retry-After
#   (before: every upload waited its turn); an image declaring more
#   voxels than 256 x --max-vertices is refused (413) before decoding;
# - event streams: at the total cap, a victim's single stream is never
#   evicted by an attacker's streams from four addresses (before: the
#   oldest stream of any address went first: the victim's), the attacker
#   evicts its own or is refused.
# Verdicts wait for states (answers, metrics, stream ends), not for time.
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
TEMPLATE3=$ROOT/examples/3d/template.mesh
# nrrd FILE N [SLICES]: an N^3 uint8 NRRD, zeros and a 12^3 cube of ones
# in the middle, gzip (plain python: no numpy needed); with SLICES, only
# that many slices of data follow the header
nrrd() {
    python3 - "$1" "$2" "${3:-$2}" <<'PY'
import sys, zlib
path, n, slices = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
c = zlib.compressobj(9, zlib.DEFLATED, 31)
out = [f"NRRD0004\ntype: uint8\ndimension: 3\nsizes: {n} {n} {n}\nencoding: gzip\n\n".encode()]
zero = bytes(n * n)
row = bytes(n // 2 - 6) + b"\1" * 12 + bytes(n - n // 2 - 6)
mid = bytes(n * (n // 2 - 6)) + row * 12 + bytes(n * (n - n // 2 - 6))
for k in range(slices):
    out.append(c.compress(mid if n // 2 - 6 <= k < n // 2 + 6 else zero))
out.append(c.flush())
open(path, "wb").write(b"".join(out))
PY
}
nrrd "$WORK/slow.nrrd" 512
# the check does all the image's work, then finds the clamp empty (422):
# the flood's jobs never reach a worker
EMPTY_CLAMP='{"clamp": {"kind": "ball", "center": [9, 9, 9], "radius": 0.1}, "max_iter": 1}'
flood_upload() { # NAME ADDRESS: a slow check from ADDRESS, code and headers in $WORK/NAME.*
    curl -sS --max-time $((300 * SLOW)) --interface "$2" -o "$WORK/$1.json" -D "$WORK/$1.hdr" \
        -w '%{http_code}' -F "template=@$TEMPLATE3" -F "target_image=@$WORK/slow.nrrd" \
        -F "params=$EMPTY_CLAMP" "$BASE/v1/jobs" >"$WORK/$1.code" 2>/dev/null
}
gauge() { # STATE: shapematch_upload_checks{state=STATE}
    curl -sS --max-time 5 "$BASE/metrics" |
        awk -v s="shapematch_upload_checks{state=\"$1\"}" '$1 == s { print $2 }'
}
waiting_at_least() { [ "$(gauge waiting)" -ge "$1" ] 2>/dev/null; }
answered() { [ -s "$WORK/$1.code" ]; }

# ---------------------------------------------- fair shares of the checks
start_daemon checks --workers 1 --check-threads 2 || { not_ok "the daemon starts"; exit 1; }
FLOOD=(f1 f2 f3 f4 f5 f6)
for f in "${FLOOD[@]}"; do
    flood_upload "$f" 127.0.0.2 &
done
if ! poll 60 waiting_at_least 4; then
    not_ok "six slow uploads from 127.0.0.2 fill the check slots" "waiting $(gauge waiting), running $(gauge running)"
    exit 1
fi
running=$(gauge running)
t0=${EPOCHREALTIME/,/.}
code=$(hcurl --interface 127.0.0.3 -o "$WORK/victim.json" -w '%{http_code}' -F "template=@$DISK" \
    -F "target_mesh=@$BOX" -F "target_sol=@$BOXSOL" -F "params=$(quick_params 5)" "$BASE/v1/jobs")
secs=$(awk -v a="$t0" -v b="${EPOCHREALTIME/,/.}" 'BEGIN { printf "%.2f", b - a }')
pending=0
for f in "${FLOOD[@]}"; do answered "$f" || pending=$((pending + 1)); done
echo "# the flood held $running check(s) running; the other address's upload: $code in $secs s, $pending of 6 flood uploads still unanswered"
check "another address's upload is checked while the flood waits: 201 with $pending of 6 flood uploads unanswered (>= 4; first come first served leaves at most 2), the flood running $running check (a slot kept for others)" \
    test "$code" = 201 -a "$pending" -ge 4 -a "$running" = 1
kill9_daemon

# ------------------------------------------- a waiting check is answered
# one slot, --check-timeout 0.25: shorter than any build's check of the
# flood (0.4-0.5 s in release; the release build kills it at the timeout,
# the sanitizer build lets it end), so every check holds the slot at least
# 0.25 s and the third of six uploads sent at once has waited longer than
# the timeout when the slot frees: answered 503.  (With 2 s, the image
# distance got fast enough that four checks ended within it: 422 x 4.)
SPOOL=
start_daemon busy --workers 1 --check-threads 1 --check-timeout 0.25 || { not_ok "the daemon starts"; exit 1; }
BUSY=(b1 b2 b3 b4 b5 b6)
pids=()
t0=${EPOCHREALTIME/,/.}
for f in "${BUSY[@]}"; do
    flood_upload "$f" 127.0.0.4 &
    pids+=($!)
done
wait "${pids[@]}"
secs=$(awk -v a="$t0" -v b="${EPOCHREALTIME/,/.}" 'BEGIN { printf "%.1f", b - a }')
codes="" busy=0
for f in "${BUSY[@]}"; do
    c=$(cat "$WORK/$f.code")
    codes="$codes $c"
    if [ "$c" = 503 ] && tr -d '\r' <"$WORK/$f.hdr" | grep -qi '^retry-after: [1-9]' &&
        jq -e '.detail | contains("--check-timeout")' "$WORK/$f.json" >/dev/null; then
        busy=$((busy + 1))
    fi
done
echo "# six slow uploads on one slot, --check-timeout 0.25: codes$codes, all answered in $secs s"
for f in "${BUSY[@]}"; do echo "# $f: $(jq -r .detail "$WORK/$f.json" 2>/dev/null | head -c 160)"; done
check "uploads that waited a whole --check-timeout for the one slot: 503 with Retry-After naming it ($busy of 6;$codes)" \
    test "$busy" -ge 1
stop_daemon

# ------------------------------------- the cost of a check, from its header
# a header declaring 10^9 voxels (1 GiB inflated, within --max-inflated
# 4G: a whole one is a 1 MB upload): more than 256 x --max-vertices 1M,
# refused from the header before decoding (before: the whole image cost
# 32 s of checking on a loaded machine); 64 slices of data suffice here
nrrd "$WORK/huge.nrrd" 1024 64
SPOOL=
start_daemon cost --workers 1 --max-vertices 1M --max-inflated 4G || { not_ok "the daemon starts"; exit 1; }
t0=${EPOCHREALTIME/,/.}
c=$(hcurl -o "$WORK/huge.json" -w '%{http_code}' -F "template=@$TEMPLATE3" -F "target_image=@$WORK/huge.nrrd" \
    -F "params=$EMPTY_CLAMP" "$BASE/v1/jobs")
secs=$(awk -v a="$t0" -v b="${EPOCHREALTIME/,/.}" 'BEGIN { printf "%.2f", b - a }')
check "a 1 MB NRRD declaring 1024^3 voxels: 413 naming --max-vertices in $secs s ($c: $(jq -r .detail "$WORK/huge.json" | head -c 200))" \
    eval '[ "$c" = 413 ] && jq -e ".detail | contains(\"1073741824 voxels\") and contains(\"--max-vertices\")" "$WORK/huge.json" >/dev/null'
stop_daemon

# ------------------------------------------------ fair shares of streams
# 12 connections, 8 reserved: 4 long-lived requests in all, 2 an address
SPOOL=
start_daemon streams --workers 1 --max-connections 12 --reserved-connections 8 \
    --max-streams-per-ip 2 || { not_ok "the daemon starts"; exit 1; }
id=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
poll 30 state_is "$id" running || not_ok "a running job to follow" "$(cat "$WORK/submit.out")"
declare -A SSE_PID
sse() { # NAME ADDRESS: a stream from ADDRESS; waits for its first event or its end
    curl -sS -N --max-time $((60 * SLOW)) --interface "$2" -H 'Accept: text/event-stream' \
        -o "$WORK/sse-$1.txt" -w '%{http_code}' "$BASE/v1/jobs/$id/events" >"$WORK/sse-$1.code" 2>/dev/null &
    SSE_PID[$1]=$!
    poll 10 eval "grep -q '^id:' '$WORK/sse-$1.txt' || ! kill -0 ${SSE_PID[$1]} 2>/dev/null"
}
alive() { kill -0 "${SSE_PID[$1]}" 2>/dev/null; }
sse victim 127.0.0.9
k=0
for round in 1 2 3; do
    for a in 2 3 4 5; do
        for s in 1 2; do
            k=$((k + 1))
            sse "a$k" "127.0.0.$a"
        done
    done
done
refused=0 evicted=0
for ((i = 1; i <= k; i++)); do
    alive "a$i" && continue
    [ "$(cat "$WORK/sse-a$i.code")" = 503 ] && refused=$((refused + 1))
    grep -q '^: evicted' "$WORK/sse-a$i.txt" && evicted=$((evicted + 1))
done
echo "# $k attacker streams from 4 addresses: $refused refused (503), $evicted evicted (their own)"
check "the victim's one stream outlives $k streams from 4 other addresses (each within --max-streams-per-ip): not evicted; the attacker's were refused ($refused) or evicted their own ($evicted)" \
    eval 'alive victim && ! grep -q "^: evicted" "$WORK/sse-victim.txt" && [ $((refused + evicted)) -gt 0 ]'
hcurl -o /dev/null -X DELETE "$BASE/v1/jobs/$id"
for ((i = 1; i <= k; i++)); do alive "a$i" && kill "${SSE_PID[a$i]}" 2>/dev/null; done
wait "${SSE_PID[victim]}" 2>/dev/null
stop_daemon

check "no sanitizer report in the daemon logs" reports_clean
echo "1..$n"
