#!/usr/bin/env bash
# deploy/Dockerfile built and run without a Docker engine (issue 10;
# `make test-deploy`, not part of `make test`):
#  - mmdebstrap makes a minimal Debian bookworm (--variant=minbase, from
#    the Debian archive this machine's apt uses), what the debian:bookworm
#    and debian:bookworm-slim images are;
#  - tests/deploy/dockerfile.py gives every stage a fresh root extracted
#    from it and runs the Dockerfile's RUN, COPY, WORKDIR, ENV and USER
#    steps in them (chroot), COPY --from copying the build stage's
#    artefacts into the runtime root;
#  - the daemon of the runtime root runs there (chroot, as the Dockerfile's
#    USER, with its ENV; only the listening address is changed to a free
#    loopback port), its HEALTHCHECK command passes inside the root, a 2D
#    job submitted with curl ends successful, and the spool's files belong
#    to the USER.
# Needs root (chroot, mount) and the network to the Debian archive.
# Env: SM_ROOT; SM_DEPLOY_MIRROR=URL overrides the mirror; SM_TEST_KEEP=1
# keeps the roots.  Prints TAP and the time of each phase.
set -u
ROOT=${SM_ROOT:-$(cd "$(dirname "$0")/../.." && pwd)}
source "$ROOT/tests/lib/tap.sh"
WORK=$ROOT/build/test-deploy/$$
T0=$SECONDS

DPID=
cleanup() {
    [ -n "$DPID" ] && kill -0 "$DPID" 2>/dev/null && kill -KILL "$DPID" 2>/dev/null
    # unmount whatever is still mounted under WORK before anything is removed
    local m
    for m in $(awk -v w="$WORK/" 'index($2, w) == 1 { print $2 }' /proc/mounts | sort -r); do
        umount "$m" 2>/dev/null || umount -l "$m" 2>/dev/null
    done
    if awk -v w="$WORK/" 'index($2, w) == 1 { found = 1 } END { exit !found }' /proc/mounts; then
        echo "# something is still mounted under $WORK: left in place"
    elif [ "$failed" -eq 0 ] && [ -z "${SM_TEST_KEEP:-}" ]; then
        rm -rf "$WORK"
    else
        echo "# kept $WORK for inspection"
    fi
}
trap cleanup EXIT
phase() { echo "# $1: $((SECONDS - T0)) s since the start"; }

if [ "$(id -u)" != 0 ]; then
    not_ok "test-deploy runs as root (chroot, mount)"
    echo "1..$n"
    exit 1
fi
if ! command -v mmdebstrap >/dev/null; then
    not_ok "mmdebstrap is installed (make test-deploy installs it)"
    echo "1..$n"
    exit 1
fi
mkdir -p "$WORK"

# the build stage's package list is a part of what the tests install
sub=$(python3 - "$ROOT/Makefile" <<'EOF'
import re, sys
text = re.sub(r"\\\n", " ", open(sys.argv[1]).read())
# the := line and every += after it
var = lambda name: set(" ".join(re.findall(r"^%s [:+]=(.*)$" % name, text, re.M)).split())
print(" ".join(sorted(var("DEB_BUILD_PACKAGES") - var("DEB_PACKAGES"))))
EOF
)
check "DEB_BUILD_PACKAGES (make deps-build) is a subset of DEB_PACKAGES${sub:+ (not: $sub)}" test -z "$sub"

# ---- the base: one mmdebstrap run, the mirrors this machine's apt uses
mirrors=$(python3 - "${SM_DEPLOY_MIRROR:-}" <<'EOF'
import glob, re, sys
uris = []
for f in sorted(glob.glob("/etc/apt/sources.list.d/*.sources")):
    for block in open(f).read().split("\n\n"):
        fields = dict(re.findall(r"^(\w[\w-]*):\s*(.*)$", block, re.M))
        if fields.get("Enabled", "yes") != "no" and "debian" in fields.get("URIs", ""):
            for u in fields["URIs"].split():
                for s in fields.get("Suites", "").split():
                    uris.append((u, s))
for f in ["/etc/apt/sources.list"] + sorted(glob.glob("/etc/apt/sources.list.d/*.list")):
    try:
        for line in open(f):
            m = re.match(r"^deb\s+(?:\[[^]]*\]\s+)?(\S+)\s+(\S+)", line)
            if m and "debian" in m.group(1):
                uris.append((m.group(1), m.group(2)))
    except OSError:
        pass
if sys.argv[1]:
    uris = [(sys.argv[1], "bookworm")]
uris = [(u, s) for u, s in uris if s.startswith("bookworm")] or [("http://deb.debian.org/debian", "bookworm")]
print("\n".join("deb %s %s main" % p for p in uris))
EOF
)
echo "# mirrors:"
echo "$mirrors" | sed 's/^/#   /'
mapfile -t mirror_args <<<"$mirrors"
t=$SECONDS
if nice mmdebstrap --variant=minbase --mode=root bookworm "$WORK/bookworm.tar" "${mirror_args[@]}" \
    >"$WORK/mmdebstrap.log" 2>&1; then
    ok "mmdebstrap made a minimal bookworm from the Debian archive ($((SECONDS - t)) s, $(du -m "$WORK/bookworm.tar" | cut -f1) MiB)"
else
    not_ok "mmdebstrap made a minimal bookworm" "$(tail -15 "$WORK/mmdebstrap.log")"
    echo "1..$n"
    exit 1
fi

# ---- the Dockerfile's stages
t=$SECONDS
if nice python3 "$ROOT/tests/deploy/dockerfile.py" "$ROOT/deploy/Dockerfile" "$ROOT" "$WORK/roots" \
    "$WORK/bookworm.tar" >"$WORK/build.log" 2>&1 && [ -f "$WORK/roots/image.json" ]; then
    ok "the Dockerfile's stages built in fresh roots ($((SECONDS - t)) s: $(jq -r '.stages | join(", ")' "$WORK/roots/image.json"))"
    grep '^# step' "$WORK/build.log"
else
    not_ok "the Dockerfile's stages build" "$(grep -v '^# step' "$WORK/build.log" | tail -30)"
    echo "1..$n"
    exit 1
fi
phase "built"
IMG=$WORK/roots/image.json
R=$(jq -r .root "$IMG")
USERSPEC=$(jq -r .user "$IMG")
check "the runtime root holds the three programs, not the sources or the compiler" \
    test -x "$R/usr/local/bin/shapematchd" -a -x "$R/usr/local/bin/shapematch-worker" \
    -a -x "$R/usr/local/bin/shapematch" -a ! -e "$R/src" -a ! -e "$R/usr/bin/gcc"

# ---- the daemon of the runtime root, as the image runs it
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
envs=()
while IFS= read -r kv; do envs+=("$kv"); done < <(jq -r '.env | to_entries[] | "\(.key)=\(.value)"' "$IMG")
envs+=("SHAPEMATCH_LISTEN=127.0.0.1:$port" "HOME=/nonexistent")
mapfile -t entry < <(jq -r '.entrypoint[]' "$IMG")
mkdir -p "$R/proc" && mount -t proc proc "$R/proc"
env -i "${envs[@]}" chroot --userspec="$USERSPEC" "$R" "${entry[@]}" >"$WORK/daemon.out" 2>"$WORK/daemon.log" &
DPID=$!
BASE=http://127.0.0.1:$port
up() { curl -fsS --max-time 2 -o /dev/null "$BASE/healthz" 2>/dev/null; }
for ((i = 0; i < 200; i++)); do up && break; kill -0 "$DPID" 2>/dev/null || break; sleep 0.1; done
if up; then
    ok "the daemon runs from the runtime root as $USERSPEC (${entry[*]})"
else
    not_ok "the daemon starts in the runtime root" "$(tail -20 "$WORK/daemon.log")"
    echo "1..$n"
    exit 1
fi
hc=$(jq -r .healthcheck "$IMG")
if [ -n "$hc" ] && env -i "${envs[@]}" chroot --userspec="$USERSPEC" "$R" /bin/sh -c "$hc"; then
    ok "the HEALTHCHECK command passes inside the root ($hc)"
else
    not_ok "the HEALTHCHECK command passes" "$hc"
fi

EX=$ROOT/examples/2d
code=$(curl -sS --max-time 30 -o "$WORK/submit.json" -w '%{http_code}' -F "template=@$EX/template.mesh" \
    -F "target_mesh=@$EX/background.mesh.gz" -F "target_sol=@$EX/background.sol.gz" \
    -F 'params={"clamp": {"kind": "ball", "center": [0.5, 0.5], "radius": 0.04}}' "$BASE/v1/jobs")
id=$(jq -r '.jobID // empty' "$WORK/submit.json" 2>/dev/null)
state=
for ((i = 0; i < 1200; i++)); do
    [ -n "$id" ] || break
    state=$(curl -sS --max-time 5 "$BASE/v1/jobs/$id" | jq -r .status)
    case $state in successful | failed | dismissed) break ;; esac
    sleep 0.25
done
curl -sS --max-time 10 -o "$WORK/summary.json" "$BASE/v1/jobs/$id/results"
if [ "$code" = 201 ] && [ "$state" = successful ] &&
    [ "$(jq -r '.status' "$WORK/summary.json")" = finished ]; then
    ok "a 2D job submitted with curl ends successful ($(jq -r '"\(.stop_reason) after \(.iterations) iterations, boundary L2 \(.boundary_l2), RMS \(.boundary_rms)"' "$WORK/summary.json"))"
else
    not_ok "a 2D job ends successful" "POST $code, state '$state'" "$(cat "$WORK/submit.json")" \
        "$(tail -10 "$WORK/daemon.log")"
fi
spool=$(jq -r '.env.SHAPEMATCH_SPOOL' "$IMG")
owner=$(stat -c %u:%g "$R$spool/jobs/$id/status.json" 2>/dev/null)
check "the spool's records belong to the Dockerfile's USER ($owner)" test "$owner" = "$USERSPEC"
kill -TERM "$DPID"
wait "$DPID"
rc=$?
DPID=
check "SIGTERM stops the daemon cleanly (exit $rc)" test "$rc" = 0
umount "$R/proc"
phase "done"
echo "# test-deploy took $((SECONDS - T0)) s"
echo "1..$n"
