#!/usr/bin/env bash
# run.sh: weight 1 seconds 60
# The documentation cannot rot: every fenced command block of README.md
# and of docs/*.md (read in that order: README first, then the pages in
# alphabetical order) is either run here verbatim (```sh blocks, in order,
# in one shell, against a real daemon: a page may use the daemon the
# README's tour starts) or is a ```console block whose every command is
# one that another suite runs (listed below with the suite that mirrors
# it); ```text and ```json blocks are never run.  A new command in a
# console block that nobody mirrors, a block of another kind, or a sh
# block that fails, fails here.  Only the daemon's address and spool are
# moved (to a free port and this suite's folder), and build/release points
# at the variant's binaries.
source "$(dirname "$0")/lib.sh"

shopt -s nullglob
docs=("$ROOT/README.md" "$ROOT"/docs/*.md)
shopt -u nullglob
blocks=$WORK/blocks
mkdir -p "$blocks"
# split each file into blocks: blocks/NNNN.<info>, numbered across the
# files in reading order; blocks.where says where each one starts
where=$WORK/blocks.where
: >"$where"
k=0
for doc in "${docs[@]}"; do
    [ -f "$doc" ] || continue
    k=$(awk -v dir="$blocks" -v k="$k" -v src="${doc#"$ROOT"/}" -v where="$where" '
      /^```/ {
        if (!inside) { inside = 1; k++; info = substr($0, 4); if (info == "") info = "none";
                       file = sprintf("%s/%04d.%s", dir, k, info); printf "" > file
                       printf "%04d %s:%d\n", k, src, NR >> where; next }
        inside = 0; close(file); next
      }
      inside { print >> file }
      END { print k }' "$doc")
done
# origin BLOCKFILE: "docs/x.md:LINE", for the messages
origin() { local b; b=$(basename "$1"); awk -v n="${b%%.*}" '$1 == n { print $2 }' "$where"; }
check "docs/ has pages besides README.md" test "${#docs[@]}" -gt 1

# console commands and the suite that runs them
mirrored() {
    case "$1" in
        "make demo") echo "tests/integration/demo.sh runs examples/demo.sh, the recipe of make demo" ;;
        "make test") echo "this very run" ;;
        *) return 1 ;;
    esac
}

nsh=0
for f in "$blocks"/*; do
    info=${f##*.}
    case "$info" in
        sh) nsh=$((nsh + 1)) ;;
        console)
            while IFS= read -r line; do
                cmd=$(printf '%s' "$line" | sed 's/[[:space:]]*#.*$//; s/[[:space:]]*$//')
                [ -z "$cmd" ] && continue
                if why=$(mirrored "$cmd"); then
                    ok "console command '$cmd' ($(origin "$f")) is exercised: $why"
                else
                    not_ok "console command '$cmd' ($(origin "$f")) is exercised by a test" "add it to a suite and to mirrored() in $0"
                fi
            done <"$f"
            ;;
        text | json | none) ;;
        *) not_ok "block at $(origin "$f") has a known kind (sh, console, text, json)" ;;
    esac
done
[ "$nsh" -gt 0 ] && ok "README.md and docs/ have $nsh runnable sh blocks" || not_ok "README.md and docs/ have runnable sh blocks"
readme_sh=0
for f in "$blocks"/*.sh; do
    case $(origin "$f") in README.md:*) readme_sh=$((readme_sh + 1)) ;; esac
done
check "README.md itself has runnable sh blocks ($readme_sh)" test "$readme_sh" -gt 0

# run the sh blocks in one shell, in a folder shaped like the repository
run=$WORK/run
mkdir -p "$run/build"
ln -s "$ROOT/examples" "$run/examples"
ln -s "$BIN" "$run/build/release"
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
{
    echo 'set -euo pipefail'
    echo 'trap '"'"'kill $(jobs -p) 2>/dev/null; wait'"'"' EXIT'
    for f in "$blocks"/*.sh; do
        echo "echo '### block $(basename "$f") at $(origin "$f")'"
        sed -e "s/127\.0\.0\.1:8080/127.0.0.1:$port/g" -e "s|/tmp/shapematch-spool|$run/spool|g" "$f"
        # the daemon needs a moment to listen: wait for its health check
        if grep -q 'shapematchd' "$f"; then
            echo "for i in \$(seq 1 $((100 * SLOW))); do curl -sf http://127.0.0.1:$port/healthz >/dev/null && break; sleep 0.1; done"
        fi
    done
} >"$run/readme.sh"
(cd "$run" && timeout $((300 * SLOW)) bash readme.sh >"$WORK/readme.out" 2>"$WORK/readme.err")
rc=$?
if [ $rc -eq 0 ]; then
    ok "every sh block of README.md and docs/*.md runs as written (exit 0)"
else
    not_ok "every sh block of README.md and docs/*.md runs as written (exit $rc)" "$(tail -n 20 "$WORK/readme.err")" "$(tail -n 5 "$WORK/readme.out")"
fi
# what the blocks produced is what the README says they produce
for f in out-3d/result.mesh out-3d/result.vtu out-3d/displacement.sol out-3d/history.csv out-3d/summary.json \
    job.json headers.txt result.vtu result.mesh displacement.sol history.csv \
    out-2d/result.mesh out-2d/summary.json out-fetched/result.mesh out-fetched/result.vtu \
    out-local-2d/result.mesh out-local-2d/summary.json; do
    check "the blocks' output $f exists" test -s "$run/$f"
done
check "the curl walk-through got 201 and a Location header" grep -qiE '^location: /v1/jobs/[0-9a-f]{32}' "$run/headers.txt"
check "the curl walk-through's events end with the status event" grep -q '"type":"status"' "$WORK/readme.out"
if command -v jq >/dev/null; then
    check "the local 3D run reached its 1e-4 boundary tolerance" \
        test "$(jq -r .stop_reason "$run/out-3d/summary.json")" = boundary_tolerance
    check "the client's --wait run reached its 1e-4 boundary tolerance" \
        test "$(jq -r .stop_reason "$run/out-2d/summary.json")" = boundary_tolerance
    check "the user guide's default 2D run stopped by itself (stalled)" \
        test "$(jq -r .stop_reason "$run/out-local-2d/summary.json")" = stalled
fi
if grep -qE 'Sanitizer|runtime error' "$WORK/readme.err" "$run"/spool/jobs/*/worker.log 2>/dev/null; then
    not_ok "no sanitizer report" "$(grep -m3 -hE 'Sanitizer|runtime error' "$WORK/readme.err" "$run"/spool/jobs/*/worker.log)"
else
    ok "no sanitizer report"
fi
