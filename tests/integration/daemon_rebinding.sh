#!/usr/bin/env bash
# DNS rebinding with the defaults (issue 37 item 3): a page on a name the
# attacker controls, resolved to the daemon's address, makes the victim's
# browser send `Host: attacker.example`.  Without --allowed-host every
# route that reads job data must refuse such a Host (421 problem+json):
# the suite walks every GET route of proto/openapi.yaml, its variables
# filled with a real job (finished, with snapshots), a real batch with its
# model and real parts, and asks each with a foreign Host (421) and with
# the names of the daemon (an address, localhost, [::1] on a v6 daemon,
# an --allowed-host, --public-url's host: not 421).  /healthz, /readyz and
# the web app's page and assets hold no job data and answer any Host.
# Before the change every reading route answered 200 to the foreign Host.
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
start_daemon rebind --workers 1 || { not_ok "the daemon starts"; exit 1; }
PORT=${BASE##*:}
FOREIGN="attacker.example:$PORT"

# a finished job with snapshots, and a batch of it with its model
J=$(submit "$DISK" "$BOX" "$BOXSOL" "$BALL_PARAMS, \"max_iter\": 20, \"save_every\": 10}")
[ -n "$J" ] && wait_state "$J" successful 60 || { not_ok "a job runs" "$(cat "$WORK/submit.out")"; exit 1; }
B=$(hcurl -H 'Content-Type: application/json' --data-binary "{\"targets\": [{\"job\": \"$J\", \"name\": \"r1\"}]}" \
    "$BASE/v1/batches" | jq -r '.batchID // empty')
batch_final() { case $(hcurl "$BASE/v1/batches/$B" | jq -r .status) in successful | failed) return 0 ;; esac; return 1; }
[ -n "$B" ] && poll 60 batch_final || { not_ok "a batch of it ends"; exit 1; }
ok "a finished job with snapshots ($J) and a batch with its model ($B)"

# the GET routes of the contract, variables filled
python3 - "$ROOT/proto/openapi.yaml" >"$WORK/routes.txt" <<'PY'
import sys, yaml
d = yaml.safe_load(open(sys.argv[1]))
for path, ops in d["paths"].items():
    if "get" in ops:
        print(path)
PY
fill() {
    local p=$1
    p=${p//\{jobID\}/$J}
    p=${p//\{batchID\}/$B}
    p=${p//\{processID\}/match}
    p=${p//\{part\}/template}
    p=${p//\{iteration\}/10}
    case $p in
    /app/*) p=${p//\{file\}/app.js} ;;
    *) p=${p//\{file\}/mean.mesh} ;;
    esac
    echo "$p"
}
# code HOST PATH [CURL ARGS]: the status (body in $WORK/b, headers in $WORK/h)
code() {
    local host=$1 path=$2
    shift 2
    hcurl -o "$WORK/b" -D "$WORK/h" -w '%{http_code}' -H "Host: $host" "$@" "$BASE$path"
}
public() { case $1 in / | /app/* | /healthz | /readyz) return 0 ;; esac; return 1; }
problem421() {
    grep -qi '^content-type: application/problem+json' "$WORK/h" &&
        jq -e '.status == 421 and (.detail | contains("attacker.example"))' "$WORK/b" >/dev/null
}

nread=0 bad="" before=""
while read -r tmpl; do
    path=$(fill "$tmpl")
    # events: an SSE stream of a finished job ends by itself; bounded anyway
    extra=()
    case $path in */events) extra=(--max-time $((10 * SLOW))) ;; esac
    own=$(code "127.0.0.1:$PORT" "$path" "${extra[@]}")
    foreign=$(code "$FOREIGN" "$path" "${extra[@]}")
    if public "$tmpl"; then
        [ "$foreign" = "$own" ] && [ "$own" = 200 ] || bad="$bad $tmpl(public: own $own, foreign $foreign)"
        continue
    fi
    nread=$((nread + 1))
    # the job was given a template, not a template_surface: nothing meshed
    # to answer (404), which still passed the Host check
    want=200
    case $tmpl in */results/template) want=404 ;; esac
    [ "$own" = "$want" ] || bad="$bad $tmpl(own Host $own)"
    [ "$foreign" = 421 ] && problem421 || bad="$bad $tmpl(foreign Host $foreign)"
done <"$WORK/routes.txt"
check "the $nread reading routes of proto/openapi.yaml answer 200 to the daemon's own Host and 421 problem+json to Host $FOREIGN; / /app /healthz /readyz 200 to both${bad:+ (bad:$bad)}" \
    test "$nread" -ge 20 -a -z "$bad"

# the names the daemon answers to, and look-alikes it refuses
bad=""
for h in "localhost:$PORT" "localhost" "app.localhost:$PORT" "127.0.0.1" "10.0.0.1:$PORT" "[::1]:$PORT"; do
    c=$(code "$h" "/v1/jobs/$J")
    [ "$c" = 200 ] || bad="$bad $h($c)"
done
for h in "localhost.attacker.example:$PORT" "127.0.0.1.attacker.example" "127.0.0.1:$PORT.x" "[::1]x" "attacker.example."; do
    c=$(code "$h" "/v1/jobs/$J")
    [ "$c" = 421 ] || bad="$bad $h($c)"
done
check "addresses (v4, [v6], with and without a port), localhost and names under it: 200; look-alikes: 421${bad:+ (bad:$bad)}" \
    test -z "$bad"
c=$(code "$FOREIGN" "/v1/jobs" -X POST -F "template=@$DISK")
check "a write with a foreign Host: 421 too ($c)" test "$c" = 421
# HTTP/1.0 without Host: no browser's request
c=$(curl -sS -0 -o /dev/null -w '%{http_code}' -H 'Host:' "$BASE/v1/jobs/$J")
check "HTTP/1.0 without Host: answered ($c)" test "$c" = 200
stop_daemon

# --allowed-host and --public-url add their names; the listen host by name
SPOOL=$WORK/rebind-spool
start_daemon named --workers 1 --allowed-host maps.example.test --public-url https://proxy.example.test/sm ||
    { not_ok "the daemon starts with --allowed-host and --public-url"; exit 1; }
PORT=${BASE##*:}
c1=$(code "maps.example.test:$PORT" "/v1/jobs/$J")
c2=$(code "proxy.example.test" "/v1/jobs/$J")
c3=$(code "attacker.example:$PORT" "/v1/jobs/$J")
check "--allowed-host's and --public-url's names 200, another 421 ($c1 $c2 $c3)" \
    test "$c1" = 200 -a "$c2" = 200 -a "$c3" = 421
stop_daemon
# a daemon on ::1: the v6 literal, the foreign name refused
"$BIN/shapematchd" --listen '[::1]:0' --spool "$WORK/v6-spool" --workers 1 2>"$WORK/v6.log" &
V6=$!
DAEMON_PIDS+=("$V6")
v6port() { jq -r 'select(.event == "listening") | .port' "$WORK/v6.log" 2>/dev/null | tail -1 | grep .; }
if poll 20 v6port >/dev/null; then
    p=$(v6port)
    c1=$(curl -sS -g -o /dev/null -w '%{http_code}' "http://[::1]:$p/v1/jobs")
    c2=$(curl -sS -g -o /dev/null -w '%{http_code}' -H "Host: attacker.example:$p" "http://[::1]:$p/v1/jobs")
    check "a daemon on [::1]: its address 200, a foreign Host 421 ($c1 $c2)" test "$c1" = 200 -a "$c2" = 421
else
    skip "no IPv6 loopback here ($(head -c 300 "$WORK/v6.log"))"
fi
check "no sanitizer report" reports_clean
echo "1..$n"
