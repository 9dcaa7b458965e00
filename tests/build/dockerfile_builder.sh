#!/usr/bin/env bash
# The Dockerfile interpreter of `make test-deploy` (tests/deploy/
# dockerfile.py), without mmdebstrap or the network: every instruction of
# deploy/Dockerfile is one it interprets; what it does not support stops
# the build with the line (before any step runs, or at the step);
# .dockerignore patterns match as BuildKit's do; COPY copies as Docker
# does (a file into a folder, a folder's content, --from a stage).
set -u
ROOT=${SM_ROOT:-$(cd "$(dirname "$0")/../.." && pwd)}
source "$ROOT/tests/lib/tap.sh"
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
PY=$ROOT/tests/deploy/dockerfile.py

words=$(python3 - "$ROOT" <<'PYEOF'
import sys
sys.path.insert(0, sys.argv[1] + "/tests/deploy")
import dockerfile as d
steps = d.instructions(sys.argv[1] + "/deploy/Dockerfile")
known = ("FROM", "RUN", "COPY", "WORKDIR", "ENV", "USER") + d.RECORDED
print(" ".join(sorted({w for _, w, _ in steps if w not in known})) or "none")
PYEOF
)
check "every instruction of deploy/Dockerfile is interpreted (unknown: $words)" test "$words" = none

# a base "image": an empty root with /etc
mkdir -p "$WORK/base/etc" "$WORK/ctx/sub/deep" "$WORK/ctx/build"
tar -C "$WORK/base" -cf "$WORK/base.tar" .
echo a >"$WORK/ctx/a.txt"; echo o >"$WORK/ctx/sub/x.o"; echo k >"$WORK/ctx/sub/deep/keep.c"
echo b >"$WORK/ctx/build/out"
printf 'build\n**/*.o\n' >"$WORK/ctx/Dockerfile.dockerignore"

# refused DOCKERFILE-TEXT EXPECTED-MESSAGE
refused() {
    local k=$1 text=$2 want=$3
    printf '%b' "$text" >"$WORK/ctx/Dockerfile"
    rm -rf "$WORK/out-$k"
    python3 "$PY" "$WORK/ctx/Dockerfile" "$WORK/ctx" "$WORK/out-$k" "$WORK/base.tar" >"$WORK/$k.out" 2>&1
    local rc=$?
    if [ $rc -eq 1 ] && grep -qF "$want" "$WORK/$k.out"; then
        ok "refused with its line: $(grep -F "$want" "$WORK/$k.out" | head -1 | sed 's/.*Dockerfile: //')"
    else
        not_ok "refused: $want" "exit $rc" "$(cat "$WORK/$k.out")"
    fi
}
refused add 'FROM debian:bookworm\nADD x /x\n' "line 2: ADD is not supported"
refused arg '# c\nARG V=1\nFROM debian:bookworm\n' "line 2: ARG is not supported"
refused img 'FROM alpine:3\n' "line 1: FROM alpine:3: only debian:bookworm, debian:bookworm-slim"
refused exec 'FROM debian:bookworm\nRUN ["true"]\n' "line 2: RUN in exec form is not supported"
refused chown 'FROM debian:bookworm\nCOPY --chown=1 a.txt /\n' "line 2: COPY --chown=1 is not supported"
refused from 'FROM debian:bookworm AS b\nCOPY --from=nope /x /\n' "line 2: COPY --from=nope: no earlier stage"
refused user 'FROM debian:bookworm\nUSER nobody\n' "line 2: USER nobody: only numeric"
refused ign 'FROM debian:bookworm\nCOPY build/out /\n' "line 2: COPY build/out: excluded by .dockerignore"
refused cont 'FROM debian:bookworm\nRUN true \\\n' "the file ends inside a continued instruction"

# COPY semantics, ignore patterns and ENV, on the empty root (no RUN)
printf '%s\n' 'FROM debian:bookworm AS one' 'WORKDIR /src' 'COPY a.txt ./' 'COPY . .' \
    'FROM debian:bookworm-slim AS two' 'COPY --from=one /src/a.txt /src/sub/deep/keep.c /bin/' \
    'ENV A=1 \' '    B="two words"' 'USER 7:8' 'ENTRYPOINT ["/bin/x"]' >"$WORK/ctx/Dockerfile"
python3 "$PY" "$WORK/ctx/Dockerfile" "$WORK/ctx" "$WORK/ok" "$WORK/base.tar" >"$WORK/ok.out" 2>&1
one=$WORK/ok/stage-0-one/src two=$WORK/ok/stage-1-two
if [ -f "$one/a.txt" ] && [ -f "$one/sub/deep/keep.c" ] && [ ! -e "$one/sub/x.o" ] && [ ! -e "$one/build" ] &&
    [ -f "$two/bin/a.txt" ] && [ -f "$two/bin/keep.c" ] && [ ! -e "$two/src" ] &&
    [ "$(jq -c '[.env.A, .env.B, .user, .entrypoint[0]]' "$WORK/ok/image.json")" = '["1","two words","7:8","/bin/x"]' ]; then
    ok "COPY (file, folder content minus build/ and **/*.o, --from), ENV, USER, ENTRYPOINT as Docker does"
else
    not_ok "COPY, ENV, USER" "$(cat "$WORK/ok.out")" "$(cd "$WORK/ok" && find . | head -30)"
fi
echo "1..$n"
