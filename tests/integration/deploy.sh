#!/usr/bin/env bash
# run.sh: weight 1 seconds 40
# deploy/: what can be checked without a Docker engine or a running systemd.
#  - `make install DESTDIR=...` produces the expected tree (programs, unit
#    with the PREFIX path) and `make uninstall` removes it;
#  - the systemd unit passes `systemd-analyze verify` without a warning, its
#    offline security exposure stays low, and (release) the daemon and a
#    worker running a job under strace use only system calls, socket
#    families, /proc files and writable paths that the unit's sandbox allows;
#  - the YAML files parse and carry what they must (probes, securityContext,
#    volumes, secret, ports, resources), and agree with each other and with
#    the Dockerfile;
#  - the Dockerfile builds with the make targets CI runs, its runtime
#    packages exist in Debian bookworm and cover every shared library the
#    built programs load, and its HEALTHCHECK command works;
#  - the daemon honours the environment of each deployment (image, compose,
#    Kubernetes, systemd): started with exactly those SHAPEMATCH_* settings
#    (listen address and spool moved to loopback and a temp folder) as an
#    unprivileged user, it starts, reports them, answers /healthz and
#    /readyz, enforces the example token and runs a job.
# Env: SM_BIN, SM_ROOT, SM_VARIANT (tests/run.sh).  Prints TAP.
set -u
ROOT=${SM_ROOT:-$(cd "$(dirname "$0")/../.." && pwd)}
BIN=${SM_BIN:-$ROOT/build/release}
VARIANT=${SM_VARIANT:-release}
W=$ROOT/build/test-integration/$VARIANT-deploy-$$
rm -rf "$W"
mkdir -p "$W"
chmod 755 "$W"
D=$ROOT/deploy
EX=$ROOT/examples/2d
SLOW=1
[ "$VARIANT" = asan ] && SLOW=4

source "$(dirname "$0")/../lib/tap.sh"
DAEMONS=()
cleanup() {
    local pid
    for pid in "${DAEMONS[@]}"; do kill -KILL "$pid" 2>/dev/null; done
    for pid in "${DAEMONS[@]}"; do wait "$pid" 2>/dev/null; done
    if [ "$failed" -eq 0 ]; then rm -rf "$W"; else echo "# kept $W"; fi
}
trap cleanup EXIT

# a python3 with PyYAML (Debian: python3-yaml)
PY=
for p in /usr/bin/python3 python3; do
    if "$p" -c 'import yaml' 2>/dev/null; then PY=$p; break; fi
done
# make as a user types it, not as a sub-make of `make test`
umake() { env -u MAKEFLAGS -u MFLAGS -u MAKELEVEL make --no-print-directory -C "$ROOT" "$@"; }

# ============================================================ make install
# (-o release: use the programs `make all` built; do not rebuild them here)
DEST=$W/dest
if umake -s -o release install DESTDIR="$DEST" PREFIX=/opt/shapematch UNITDIR=/etc/systemd/system \
    >"$W/install.out" 2>&1; then
    ok "make install DESTDIR=... PREFIX=/opt/shapematch succeeds"
else
    not_ok "make install DESTDIR=... PREFIX=/opt/shapematch succeeds" "$(cat "$W/install.out")"
fi
# (the libraries, headers, man pages and Python package: tests/build/install.sh)
tree=$(cd "$DEST" 2>/dev/null && find . -type f -printf '%p %m\n' | grep -E '/bin/|/systemd/' | sort)
want_tree=$(printf '%s\n' "./etc/systemd/system/shapematchd.service 644" "./opt/shapematch/bin/shapematch 755" \
    "./opt/shapematch/bin/shapematch-worker 755" "./opt/shapematch/bin/shapematchd 755")
if [ "$tree" = "$want_tree" ]; then
    ok "installed tree: the three programs (755) in PREFIX/bin, the unit (644) in /etc/systemd/system"
else
    not_ok "installed tree is the programs and the unit" "got:" "$tree" "expected:" "$want_tree"
fi
unit_inst=$DEST/etc/systemd/system/shapematchd.service
if grep -qx 'ExecStart=/opt/shapematch/bin/shapematchd' "$unit_inst" 2>/dev/null &&
    ! grep -q '/usr/local/bin' "$unit_inst" &&
    diff <(sed 's|/usr/local/bin/|/opt/shapematch/bin/|g' "$D/systemd/shapematchd.service") "$unit_inst" >/dev/null; then
    ok "the installed unit runs PREFIX/bin/shapematchd and is otherwise deploy/systemd/shapematchd.service"
else
    not_ok "the installed unit's ExecStart follows PREFIX" "$(grep -n 'ExecStart\|/usr/local' "$unit_inst" 2>&1)"
fi
if cmp -s "$DEST/opt/shapematch/bin/shapematchd" "$ROOT/build/release/shapematchd" &&
    "$DEST/opt/shapematch/bin/shapematchd" --version >/dev/null 2>&1 &&
    "$DEST/opt/shapematch/bin/shapematch" --help >/dev/null 2>&1; then
    ok "the installed programs are the release build and run"
else
    not_ok "the installed programs are the release build and run"
fi
umake -s uninstall DESTDIR="$DEST" PREFIX=/opt/shapematch UNITDIR=/etc/systemd/system >"$W/uninstall.out" 2>&1
left=$(find "$DEST" -type f 2>/dev/null)
if [ -z "$left" ]; then ok "make uninstall removes what make install put"; else not_ok "make uninstall removes everything" "$left"; fi

# ================================================================ systemd
# A second install whose paths exist on this machine, so that verify can
# check the program too.
umake -s -o release install PREFIX="$W/prefix" UNITDIR="$W/units" >"$W/install2.out" 2>&1
UNIT=$W/units/shapematchd.service
if ! command -v systemd-analyze >/dev/null; then
    not_ok "systemd-analyze is installed (Debian package systemd, in DEB_PACKAGES)"
else
    out=$(cd "$W" && systemd-analyze verify "$UNIT" 2>&1)
    rc=$?
    if [ "$rc" -eq 0 ] && [ -z "$out" ]; then
        ok "systemd-analyze verify: no error, no warning"
    else
        not_ok "systemd-analyze verify: no error, no warning" "status $rc" "$out"
    fi
    # the check can fail: a misspelt setting is reported
    sed 's/^ProtectSystem=strict/ProtectSystem=strikt/' "$UNIT" >"$W/units/broken.service"
    out=$(cd "$W" && systemd-analyze verify "$W/units/broken.service" 2>&1)
    if [ -n "$out" ]; then ok "... and it does report a misspelt value"; else not_ok "systemd-analyze verify reports a misspelt value"; fi
    exposure=$(systemd-analyze security --offline=yes "$UNIT" 2>/dev/null |
        sed -n 's/.*Overall exposure level for shapematchd.service: \([0-9.]*\).*/\1/p')
    if [ -n "$exposure" ] && awk -v e="$exposure" 'BEGIN { exit !(e <= 2.0) }'; then
        ok "systemd-analyze security --offline: exposure $exposure <= 2.0"
    else
        not_ok "systemd-analyze security --offline: exposure <= 2.0" "got '$exposure'"
    fi
fi
# the hardening the issue asks for, as written in the unit
missing=
for kv in DynamicUser=yes StateDirectory=shapematch ProtectSystem=strict NoNewPrivileges=yes \
    PrivateTmp=yes ProtectHome=yes SystemCallArchitectures=native CapabilityBoundingSet= \
    'RestrictAddressFamilies=AF_INET AF_INET6 AF_UNIX' 'Environment=SHAPEMATCH_SPOOL=%S/shapematch' \
    KillMode=mixed; do
    grep -qxF "$kv" "$D/systemd/shapematchd.service" || missing="$missing [$kv]"
done
check "unit has DynamicUser, StateDirectory spool, ProtectSystem=strict, NoNewPrivileges, PrivateTmp, ProtectHome, RestrictAddressFamilies, native syscalls, KillMode=mixed" \
    test -z "$missing"
[ -z "$missing" ] || echo "#   missing:$missing"

# ======================================================= files and fields
if [ -z "$PY" ]; then
    not_ok "python3 with PyYAML (Debian python3-yaml, in DEB_PACKAGES) is installed"
else
    # The checker prints PASS/FAIL lines and writes, for the daemon runs
    # below, the effective environment of each deployment ($W/env-K) and
    # its token file ($W/tokens-K), plus the Dockerfile's runtime packages,
    # copied programs and health-check command.
    "$PY" - "$ROOT" "$W" >"$W/fields.out" 2>&1 <<'PYEOF'
import base64, os, re, shlex, sys
import yaml

root, work = sys.argv[1], sys.argv[2]
deploy = os.path.join(root, "deploy")

def result(ok, desc, detail=""):
    print(("PASS " if ok else "FAIL ") + desc + ("" if ok or not detail else " :: " + str(detail)))

def size_bytes(text):
    """Sizes as the daemon reads them (K/M/G/T = 2^10..., optional i, B)
    and Kubernetes quantities (Ki/Mi/Gi, or plain bytes)."""
    m = re.fullmatch(r"(\d+)\s*([kKmMgGtT]?)(i?)([bB]?)", str(text).strip())
    if not m:
        raise ValueError("not a size: %r" % text)
    return int(m.group(1)) << {"": 0, "k": 10, "m": 20, "g": 30, "t": 40}[m.group(2).lower()]

def seconds(text):
    """Durations as the daemon (s/m/h/d suffix) and compose (1m30s) write them."""
    text = str(text).strip()
    if re.fullmatch(r"\d+(\.\d*)?", text):
        return float(text)
    total, pos = 0.0, 0
    for m in re.finditer(r"(\d+(?:\.\d*)?)(ms|s|m|h|d)", text):
        if m.start() != pos:
            raise ValueError("not a duration: %r" % text)
        total += float(m.group(1)) * {"ms": 0.001, "s": 1, "m": 60, "h": 3600, "d": 86400}[m.group(2)]
        pos = m.end()
    if pos != len(text) or pos == 0:
        raise ValueError("not a duration: %r" % text)
    return total

def cpus(text):
    text = str(text)
    return int(text[:-1]) / 1000 if text.endswith("m") else float(text)

def listen_port(env):
    return int(env["SHAPEMATCH_LISTEN"].rsplit(":", 1)[1])

def graces(env):
    # the daemon's defaults: 10 s for jobs to finish, 5 s before SIGKILL
    return seconds(env.get("SHAPEMATCH_SHUTDOWN_GRACE", "10s")) + seconds(env.get("SHAPEMATCH_KILL_GRACE", "5s"))

def write_env(kind, env):
    with open(os.path.join(work, "env-" + kind), "w") as f:
        for k in sorted(env):
            f.write("%s=%s\n" % (k, env[k]))

makefile = open(os.path.join(root, "Makefile")).read()
version = re.search(r"^VERSION := (\S+)", makefile, re.M).group(1)

# ------------------------------------------------------------ Dockerfile
lines, cur = [], ""
for raw in open(os.path.join(deploy, "Dockerfile")):
    s = raw.rstrip("\n")
    if not cur and (not s.strip() or s.lstrip().startswith("#")):
        continue
    if s.lstrip().startswith("#"):
        continue
    if s.endswith("\\"):
        cur += s[:-1] + " "
        continue
    lines.append((cur + s).strip())
    cur = ""
stages = []
for line in lines:
    word, _, rest = line.partition(" ")
    word = word.upper()
    if word == "FROM":
        parts = rest.split()
        stages.append({"image": parts[0], "name": parts[2] if len(parts) > 2 and parts[1].upper() == "AS" else None,
                       "run": [], "copy": [], "env": {}, "other": {}})
    elif word == "RUN":
        stages[-1]["run"].append(rest)
    elif word == "COPY":
        stages[-1]["copy"].append(line)
    else:
        stages[-1]["other"].setdefault(word, []).append(rest.strip())
        if word == "ENV":
            for tok in shlex.split(rest):
                k, _, v = tok.partition("=")
                stages[-1]["env"][k] = v
result(len(stages) >= 2 and all(re.fullmatch(r"debian:bookworm(-slim)?", s["image"]) for s in stages),
       "Dockerfile: multi-stage, every stage on debian:bookworm", [s["image"] for s in stages])
build, runtime = stages[0], stages[-1]
build_cmds = " && ".join(build["run"])
# make as a command (not the package name in "apt-get install make ...")
make_targets = re.findall(r"(?:^|&&|;)\s*make((?:\s+-\S+)*)\s+([a-z][a-z-]*)", build_cmds)
targets = [t for _, t in make_targets]
ci = open(os.path.join(root, ".ci", "run")).read()
test_recipe = re.search(r"^test:([^\n]*)\n((?:\t[^\n]*\n)+)", makefile, re.M)
ci_steps = "make test" in ci and test_recipe and "deps" in test_recipe.group(1) and re.search(r"\$\(MAKE\)( -j\S+)? all\b", test_recipe.group(2))
all_has_release = re.search(r"^all: \$\(foreach v,\$\(VARIANTS\)", makefile, re.M) and "VARIANTS := release" in makefile
result(targets[:2] == ["deps-build", "release"] and "install" in targets and ci_steps and all_has_release
       and all(re.search(r"^%s:" % t, makefile, re.M) for t in targets),
       "Dockerfile build stage runs make deps-build, make release, make install (CI: make test = deps + all, all includes release)",
       targets)
# debian:bookworm has no make: the build stage must install it before it runs make
first_make = re.search(r"(?:^|&&|;)\s*make\b", build_cmds)
before = build_cmds[:first_make.start()] if first_make else ""
result(build["image"] == "debian:bookworm" and first_make is not None
       and re.search(r"apt-get install[^&;]*\smake(\s|$)", before) is not None,
       "Dockerfile build stage installs make (absent from debian:bookworm) before it runs make",
       build_cmds[:200])
install_run = [r for r in build["run"] if "make install" in r]
m = re.search(r"make install DESTDIR=(\S+) PREFIX=(\S+)", install_run[0]) if install_run else None
copied, libs = [], []
for c in runtime["copy"]:
    toks = c.split()
    if any(t.startswith("--from=") for t in toks):
        srcs = [t for t in toks[1:-1] if not t.startswith("--")]
        if all("/lib/" in t for t in srcs):
            libs += [(t, toks[-1]) for t in srcs]  # the template mesher's Netgen shim
            continue
        copied += srcs
        copy_dest = toks[-1]
expected_srcs = sorted("%s%s/bin/%s" % (m.group(1), m.group(2), p) for p in ("shapematchd", "shapematch-worker", "shapematch")) if m else None
result(m is not None and sorted(copied) == expected_srcs,
       "Dockerfile runtime stage copies exactly the three installed programs from the build stage", copied)
# the programs open the shim from ../lib beside them (core/sm_template_mesh.c)
expected_libs = [("%s%s/lib/libshapematch_nglib.so.0" % (m.group(1), m.group(2)),
                  os.path.normpath(copy_dest + "/../lib") + "/")] if m and copied else None
result(libs == expected_libs,
       "Dockerfile runtime stage copies the installed Netgen shim to the lib folder beside the programs", libs)
with open(os.path.join(work, "docker-programs"), "w") as f:
    f.write("\n".join(os.path.basename(c) for c in copied) + "\n")
pkgs = []
for r in runtime["run"]:
    mm = re.search(r"apt-get install((?:\s+[-\w.+=]+)+)", r)
    if mm:
        pkgs += [t for t in mm.group(1).split() if not t.startswith("-")]
with open(os.path.join(work, "runtime-packages"), "w") as f:
    f.write("\n".join(pkgs) + "\n")
result(bool(pkgs) and all("rm -rf /var/lib/apt/lists" in r for r in runtime["run"] if "apt-get install" in r),
       "Dockerfile runtime stage installs its packages and drops the apt lists", pkgs)
image_env = dict(runtime["env"])
user = runtime["other"].get("USER", [""])[-1]
uid = user.split(":")[0]
result(uid.isdigit() and int(uid) != 0, "Dockerfile runs as a numeric non-root user", user)
expose = runtime["other"].get("EXPOSE", [])
port = listen_port(image_env) if "SHAPEMATCH_LISTEN" in image_env else None
result(image_env.get("SHAPEMATCH_LISTEN", "").startswith("0.0.0.0:") and expose == [str(port)],
       "Dockerfile listens on 0.0.0.0:%s and EXPOSEs that port" % port, (image_env.get("SHAPEMATCH_LISTEN"), expose))
vol = runtime["other"].get("VOLUME", [])
vols = yaml.safe_load(vol[0]) if vol else []
vols = vols if isinstance(vols, list) else [vols]
result(image_env.get("SHAPEMATCH_SPOOL") in vols, "Dockerfile declares the spool SHAPEMATCH_SPOOL as a VOLUME", (image_env.get("SHAPEMATCH_SPOOL"), vols))
hc = runtime["other"].get("HEALTHCHECK", [""])[-1]
hc_cmd = hc.split(" CMD ", 1)[1] if " CMD " in hc else ""
result("/healthz" in hc_cmd, "Dockerfile HEALTHCHECK queries /healthz", hc)
with open(os.path.join(work, "healthcheck-cmd"), "w") as f:
    f.write(hc_cmd + "\n")
entry = runtime["other"].get("ENTRYPOINT", [""])[-1]
result(entry in ('["%sshapematchd"]' % copy_dest, '["%s/shapematchd"]' % copy_dest.rstrip("/")),
       "Dockerfile ENTRYPOINT is the copied shapematchd", entry)
result(graces(image_env) <= 10, "image graces (%g s) fit docker stop's default 10 s" % graces(image_env))
write_env("docker", image_env)

# ---------------------------------------------------------- compose.yaml
compose = yaml.safe_load(open(os.path.join(deploy, "compose.yaml")))
svc = compose["services"]["shapematchd"]
b = svc.get("build", {})
result(os.path.normpath(os.path.join(deploy, b.get("context", ""))) == os.path.normpath(root)
       and b.get("dockerfile") == "deploy/Dockerfile",
       "compose builds deploy/Dockerfile with the repository as context", b)
cenv = svc.get("environment", {})
if isinstance(cenv, list):
    cenv = dict(e.split("=", 1) for e in cenv)
cenv = {k: str(v) for k, v in cenv.items()}
eff = dict(image_env)
eff.update(cenv)
cport = listen_port(eff)
ports = [str(p) for p in svc.get("ports", [])]
result(ports and all(p.startswith("127.0.0.1:") and p.endswith(":%d" % cport) for p in ports),
       "compose publishes the daemon's port %d on the host's loopback" % cport, ports)
spool = eff.get("SHAPEMATCH_SPOOL")
named = compose.get("volumes") or {}
mounts = [v.split(":") for v in svc.get("volumes", []) if isinstance(v, str)]
result(any(m[0] in named and m[1] == spool for m in mounts),
       "compose mounts a named volume (declared at top level) on the spool %s" % spool, mounts)
secrets = compose.get("secrets") or {}
svc_secrets = [s if isinstance(s, str) else s.get("source") for s in svc.get("secrets", [])]
tok = eff.get("SHAPEMATCH_TOKENS_FILE", "")
sec_name = tok[len("/run/secrets/"):] if tok.startswith("/run/secrets/") else None
sec_file = None
if sec_name in secrets and "file" in secrets[sec_name]:
    sec_file = re.sub(r"\$\{[A-Z_]+:-([^}]*)\}", r"\1", secrets[sec_name]["file"])
    sec_file = os.path.normpath(os.path.join(deploy, sec_file))
result(sec_name in svc_secrets and sec_file and os.path.isfile(sec_file),
       "compose gives the token file as a secret, SHAPEMATCH_TOKENS_FILE=/run/secrets/<it>, its default file exists",
       (tok, svc_secrets, sec_file))
if sec_file and os.path.isfile(sec_file):
    with open(os.path.join(work, "tokens-compose"), "w") as f:
        f.write(open(sec_file).read())
    result("EXAMPLE" in open(sec_file).read(), "compose's default token file is marked as an example")
u = str(svc.get("user", "")).split(":")[0]
result(svc.get("read_only") is True and "/tmp" in (svc.get("tmpfs") or []) and svc.get("cap_drop") == ["ALL"]
       and "no-new-privileges:true" in (svc.get("security_opt") or []) and u.isdigit() and int(u) != 0,
       "compose: read-only root, /tmp tmpfs, no capability, no-new-privileges, non-root user", svc.get("user"))
result(seconds(svc.get("stop_grace_period", "10s")) >= graces(eff) + 1,
       "compose stop_grace_period covers the daemon's shutdown + kill grace (%g s)" % graces(eff))
hct = (svc.get("healthcheck") or {}).get("test", [])
result(any(("127.0.0.1:%d/healthz" % cport) in t for t in hct), "compose healthcheck queries /healthz on the daemon's port", hct)
result(svc.get("image", "").endswith(":" + version), "compose image tag is the Makefile VERSION %s" % version, svc.get("image"))
write_env("compose", eff)

# -------------------------------------------------------------- k8s/*.yaml
k8sdir = os.path.join(deploy, "k8s")
docs = {}
for fn in sorted(os.listdir(k8sdir)):
    if fn.endswith(".yaml") and fn != "kustomization.yaml":
        for doc in yaml.safe_load_all(open(os.path.join(k8sdir, fn))):
            if doc:
                docs.setdefault(doc["kind"], []).append(doc)
kust = yaml.safe_load(open(os.path.join(k8sdir, "kustomization.yaml")))
listed = sorted(kust.get("resources", []))
present = sorted(f for f in os.listdir(k8sdir) if f.endswith(".yaml") and f != "kustomization.yaml")
result(listed == present, "kustomization.yaml lists every manifest", (listed, present))
result(all(k in docs for k in ("Deployment", "Service", "PersistentVolumeClaim", "Secret")),
       "k8s: Deployment, Service, PersistentVolumeClaim and Secret", sorted(docs))
dep = docs["Deployment"][0]
spec = dep["spec"]
pod = spec["template"]["spec"]
labels = spec["template"]["metadata"]["labels"]
result(spec.get("replicas") == 1 and spec.get("strategy", {}).get("type") == "Recreate"
       and all(labels.get(k) == v for k, v in spec["selector"]["matchLabels"].items()),
       "Deployment: one replica, Recreate (one daemon per spool), selector matches the pod", (spec.get("replicas"), spec.get("strategy")))
c = pod["containers"][0]
kenv = {e["name"]: str(e["value"]) for e in c.get("env", []) if "value" in e}
keff = dict(image_env)
keff.update(kenv)
kport = listen_port(keff)
cports = {p.get("name"): p["containerPort"] for p in c.get("ports", [])}
def port_of(ref):
    return cports.get(ref) if isinstance(ref, str) else ref
result(keff["SHAPEMATCH_LISTEN"].startswith("0.0.0.0:") and kport in cports.values(),
       "Deployment: containerPort %d is the daemon's SHAPEMATCH_LISTEN port" % kport, cports)
rp, lp = c.get("readinessProbe", {}).get("httpGet", {}), c.get("livenessProbe", {}).get("httpGet", {})
result(rp.get("path") == "/readyz" and port_of(rp.get("port")) == kport, "Deployment: readiness probe GET /readyz on the daemon's port", rp)
result(lp.get("path") == "/healthz" and port_of(lp.get("port")) == kport, "Deployment: liveness probe GET /healthz on the daemon's port", lp)
res = c.get("resources", {})
req, lim = res.get("requests", {}), res.get("limits", {})
try:
    res_ok = all(k in req and k in lim for k in ("cpu", "memory")) and cpus(req["cpu"]) <= cpus(lim["cpu"]) \
        and size_bytes(req["memory"]) <= size_bytes(lim["memory"])
except (ValueError, KeyError):
    res_ok = False
result(res_ok, "Deployment: cpu and memory requests and limits, requests <= limits", res)
workers = int(keff.get("SHAPEMATCH_WORKERS", "0"))
try:
    fits = workers >= 1 and workers <= cpus(lim["cpu"]) and \
        workers * size_bytes(keff.get("SHAPEMATCH_MEMORY_LIMIT", "4G")) < size_bytes(lim["memory"])
except (ValueError, KeyError):
    fits = False
result(fits, "Deployment: SHAPEMATCH_WORKERS (%d) <= cpu limit, workers x SHAPEMATCH_MEMORY_LIMIT < memory limit" % workers,
       (keff.get("SHAPEMATCH_WORKERS"), keff.get("SHAPEMATCH_MEMORY_LIMIT"), lim))
psc, csc = pod.get("securityContext", {}), c.get("securityContext", {})
run_as = csc.get("runAsUser", psc.get("runAsUser"))
result((csc.get("runAsNonRoot") or psc.get("runAsNonRoot")) is True and run_as not in (None, 0)
       and csc.get("readOnlyRootFilesystem") is True and csc.get("allowPrivilegeEscalation") is False
       and csc.get("capabilities", {}).get("drop") == ["ALL"] and not csc.get("privileged", False),
       "Deployment: runAsNonRoot (uid %s), readOnlyRootFilesystem, no privilege escalation, capabilities dropped" % run_as, csc)
result(str(run_as) == uid, "Deployment runs as the image's user (%s)" % uid, run_as)
vols = {v["name"]: v for v in pod.get("volumes", [])}
vm = {m["mountPath"]: m for m in c.get("volumeMounts", [])}
kspool = keff.get("SHAPEMATCH_SPOOL", "")
pvc = docs["PersistentVolumeClaim"][0]
sm = vm.get(kspool)
result(sm is not None and vols.get(sm["name"], {}).get("persistentVolumeClaim", {}).get("claimName") == pvc["metadata"]["name"]
       and not sm.get("readOnly", False),
       "Deployment mounts the PersistentVolumeClaim %s on the spool %s" % (pvc["metadata"]["name"], kspool), vm)
result(bool(pvc["spec"].get("accessModes")) and "storage" in pvc["spec"].get("resources", {}).get("requests", {}),
       "PersistentVolumeClaim: access mode and storage request", pvc["spec"])
result(psc.get("fsGroup") is not None and str(psc.get("fsGroup")) == str(psc.get("runAsGroup", csc.get("runAsGroup"))),
       "Deployment: fsGroup makes the spool volume writable by the daemon's group", psc)
ktok = keff.get("SHAPEMATCH_TOKENS_FILE", "")
secret = docs["Secret"][0]
sdata = dict(secret.get("stringData") or {})
for k, v in (secret.get("data") or {}).items():
    sdata[k] = base64.b64decode(v).decode()
tdir, tkey = os.path.dirname(ktok), os.path.basename(ktok)
tm = vm.get(tdir)
tv = vols.get(tm["name"], {}).get("secret", {}) if tm else {}
result(tm is not None and tm.get("readOnly") is True and tv.get("secretName") == secret["metadata"]["name"] and tkey in sdata,
       "Deployment mounts the Secret %s read-only; SHAPEMATCH_TOKENS_FILE is its key '%s'" % (secret["metadata"]["name"], tkey), (ktok, tm, tv))
result(tv.get("defaultMode", 0o644) & 0o007 == 0, "the token file is not world-readable (defaultMode %o)" % tv.get("defaultMode", 0o644))
if tkey in sdata:
    with open(os.path.join(work, "tokens-k8s"), "w") as f:
        f.write(sdata[tkey])
    marked = "EXAMPLE" in sdata[tkey] and "EXAMPLE" in open(os.path.join(k8sdir, "secret.yaml")).read()
    result(marked, "the Secret's token is clearly marked as an example")
tmp = vm.get("/tmp")
result(tmp is not None and "emptyDir" in vols.get(tmp["name"], {}), "Deployment: /tmp is an emptyDir (the root is read-only)", vm)
result(pod.get("terminationGracePeriodSeconds", 30) >= graces(keff) + 1,
       "terminationGracePeriodSeconds covers the daemon's shutdown + kill grace (%g s)" % graces(keff))
svc_k = docs["Service"][0]
sp = svc_k["spec"]["ports"][0]
result(all(labels.get(k) == v for k, v in svc_k["spec"]["selector"].items()) and port_of(sp.get("targetPort")) == kport,
       "Service selects the daemon's pod and targets its port", svc_k["spec"])
result(c.get("image") == svc.get("image"), "Deployment and compose run the same image", (c.get("image"), svc.get("image")))
write_env("k8s", keff)

# ----------------------------------------------------------- systemd unit
senv = {}
for line in open(os.path.join(deploy, "systemd", "shapematchd.service")):
    line = line.strip()
    if line.startswith("Environment="):
        for tok in shlex.split(line[len("Environment="):]):
            k, _, v = tok.partition("=")
            senv[k] = v
    if line.startswith("TimeoutStopSec="):
        stop_timeout = seconds(line.split("=", 1)[1])
result(stop_timeout >= graces(senv) + 1, "unit TimeoutStopSec covers the daemon's shutdown + kill grace (%g s)" % graces(senv))
write_env("systemd", senv)
PYEOF
    rc=$?
    while IFS= read -r line; do
        case $line in
        PASS\ *) ok "${line#PASS }" ;;
        FAIL\ *) d=${line#FAIL }; not_ok "${d%% :: *}" "${d#* :: }" ;;
        esac
    done <"$W/fields.out"
    if [ "$rc" -ne 0 ]; then not_ok "the deployment files parse (YAML, Dockerfile)" "$(grep -v '^PASS\|^FAIL' "$W/fields.out")"; fi
fi

# ============================================== runtime packages of the image
# One apt-cache call (each loads the whole cache, ~1 s): the dependency
# graph below the list.  Edges follow real packages only: for a virtual one
# such as libblas.so.3 only a provider the list names itself counts (else
# apt would pick another BLAS).
[ -s "$W/runtime-packages" ] &&
    apt-cache depends --recurse --no-recommends --no-suggests --no-conflicts --no-breaks \
        --no-replaces --no-enhances $(cat "$W/runtime-packages") libc6 2>/dev/null |
    awk '/^[^ <]/ { p = $1; print p, p; next } /^ .Depends: [^<]/ { print p, $2 }' |
        sed 's/:[a-z0-9]*//g' | sort -u >"$W/graph"
# closure ROOTS...: the packages installed with ROOTS, plus the base
# image's essential and required ones
closure() {
    awk -v roots="$*" 'BEGIN { n = split(roots, r, " "); for (i = 1; i <= n; i++) q[++t] = r[i] }
        { edge[$1] = edge[$1] " " $2 }
        END {
            for (h = 1; h <= t; h++) {
                p = q[h]; if (p in seen) continue; seen[p] = 1; print p
                m = split(edge[p], d, " "); for (i = 1; i <= m; i++) if (!(d[i] in seen)) q[++t] = d[i]
            }
        }' "$W/graph"
    dpkg-query -W -f '${Package} ${Essential} ${Priority}\n' 2>/dev/null |
        awk '$2 == "yes" || $3 == "required" { print $1 }'
}
# uncovered CLOSURE_FILE: the libraries whose package is not in it
uncovered() {
    local lib real short owner
    while read -r lib real short; do
        owner=$(awk -v a="$real" -v b="$short" '$2 == a || $2 == b { print $1; exit }' "$W/owners")
        grep -qx "${owner:-none}" "$1" || printf ' %s(%s)' "$(basename "$lib")" "${owner:-no package}"
    done <"$W/libs"
}
if [ ! -s "$W/runtime-packages" ]; then
    not_ok "the Dockerfile's runtime packages are known"
elif [ ! -s "$W/graph" ]; then
    skip "apt has no package lists here (apt-get update): runtime packages not checked"
else
    awk '$1 == $2 { print $1 }' "$W/graph" >"$W/known-packages"
    unknown=$(sort -u "$W/runtime-packages" | comm -23 - "$W/known-packages" | tr '\n' ' ')
    check "every runtime package of the Dockerfile exists in Debian: $(tr '\n' ' ' <"$W/runtime-packages")" test -z "$unknown"
    [ -z "$unknown" ] || echo "#   unknown: $unknown"
    # the libraries (resolved) and their packages, in one dpkg call: dpkg
    # knows the path a package shipped, /lib/... or /usr/lib/...
    # what ldd lists, and what the client opens with dlopen when it first
    # talks to a daemon (client/curl_api.c: CURL_SONAME) with its own needs
    dlopened=$(sed -n 's/^#define CURL_SONAME "\(.*\)"$/\1/p' "$ROOT/client/curl_api.c")
    dlopened=$(ldconfig -p | awk -v n="$dlopened" '$1 == n { print $NF; exit }')
    for bin in "$ROOT/build/release/shapematchd" "$ROOT/build/release/shapematch-worker" \
        "$ROOT/build/release/shapematch" $dlopened; do
        [ "$bin" = "$dlopened" ] && echo "$bin"
        ldd "$bin" 2>/dev/null | awk '/=> \// { print $3 }'
    done | sort -u | while read -r lib; do
        real=$(readlink -f "$lib")
        printf '%s %s %s\n' "$lib" "$real" "${real#/usr}"
    done >"$W/libs"
    dpkg -S $(awk '{ print $2, $3 }' "$W/libs") 2>/dev/null | sed 's/^\([^:]*\)\(:[a-z0-9]*\)*: /\1 /' >"$W/owners"
    nlibs=$(grep -c . "$W/libs")
    closure $(cat "$W/runtime-packages") libc6 | sort -u >"$W/closure"
    missing=$(uncovered "$W/closure")
    if [ "$nlibs" -gt 0 ] && [ -z "$missing" ]; then
        ok "the runtime packages provide every shared library the three programs load ($nlibs, ldd; libcurl through dlopen${dlopened:+: $dlopened})"
    else
        not_ok "the runtime packages provide every shared library the programs load" "not covered:$missing (libs: $nlibs)"
    fi
    # the check can fail: without libcholmod3 in the list, CHOLMOD is missing
    closure $(grep -vx libcholmod3 "$W/runtime-packages") libc6 | sort -u >"$W/closure-minus"
    missing=$(uncovered "$W/closure-minus")
    if [[ $missing == *"libcholmod.so.3(libcholmod3)"* ]]; then ok "... and a list without libcholmod3 would be caught"; else not_ok "a list without libcholmod3 would be caught" "$missing"; fi
fi

# ================================================ the deployments' settings
# Every SHAPEMATCH_* variable a deployment sets is one the daemon reads.
"$BIN/shapematchd" --help >"$W/help.txt" 2>&1
unknown=
for kind in docker compose k8s systemd; do
    [ -f "$W/env-$kind" ] || continue
    for v in $(grep -o '^SHAPEMATCH_[A-Z_]*' "$W/env-$kind"); do
        grep -q "env $v;" "$W/help.txt" || unknown="$unknown $kind:$v"
    done
done
nset=$(cat "$W"/env-* 2>/dev/null | grep -c '^SHAPEMATCH_')
check "every SHAPEMATCH_* variable the deployment files set ($nset settings) is one shapematchd --help documents" \
    test -n "$nset" -a "$nset" -gt 0 -a -z "$unknown"
[ -z "$unknown" ] || echo "#   unknown:$unknown"

# run as an unprivileged user (the image's and Kubernetes' non-root uid,
# systemd's dynamic user) when this test runs as root
AS_USER=()
if [ "$(id -u)" = 0 ] && command -v setpriv >/dev/null; then
    AS_USER=(setpriv --reuid=65534 --regid=65534 --clear-groups)
    # a checkout in a private folder (mktemp -d is 0700) cannot be entered
    # by that user: then the daemons run as root, the environments are
    # still checked
    if ! "${AS_USER[@]}" test -x "$BIN/shapematchd" -a -x "$BIN/shapematch-worker" -a -x "$W"; then
        echo "# $ROOT is not reachable by uid 65534: the deployment daemons run as root"
        AS_USER=()
    fi
fi
DPID=
PORT=
# start_env KIND [VAR=VALUE...]: shapematchd with exactly the deployment's
# environment (plus PATH), listen/spool/tokens moved here; sets DPID, PORT
start_env() {
    local kind=$1
    shift
    local spool=$W/spool-$kind log=$W/daemon-$kind.log
    rm -rf "$spool"
    mkdir -p "$spool"
    local -a envs=()
    local line name
    while IFS= read -r line; do
        name=${line%%=*}
        case $name in
        SHAPEMATCH_LISTEN) line=SHAPEMATCH_LISTEN=127.0.0.1:0 ;;
        SHAPEMATCH_SPOOL) line=SHAPEMATCH_SPOOL=$spool ;;
        SHAPEMATCH_TOKENS_FILE)
            cp "$W/tokens-$kind" "$W/tokens-$kind.run"
            chmod 400 "$W/tokens-$kind.run"
            [ "${#AS_USER[@]}" -gt 0 ] && chown 65534:65534 "$W/tokens-$kind.run"
            line=SHAPEMATCH_TOKENS_FILE=$W/tokens-$kind.run ;;
        esac
        envs+=("$line")
    done <"$W/env-$kind"
    # the systemd unit has no SHAPEMATCH_LISTEN: the default port is not ours
    grep -q '^SHAPEMATCH_LISTEN=' "$W/env-$kind" || envs+=(SHAPEMATCH_LISTEN=127.0.0.1:0)
    grep -q '^SHAPEMATCH_SPOOL=' "$W/env-$kind" || envs+=("SHAPEMATCH_SPOOL=$spool")
    # sanitizer settings of the test run pass through (asan variant)
    local v
    for v in ASAN_OPTIONS UBSAN_OPTIONS LSAN_OPTIONS; do
        [ -n "${!v:-}" ] && envs+=("$v=${!v}")
    done
    [ "${#AS_USER[@]}" -gt 0 ] && chown 65534:65534 "$spool"
    : >"$log"
    (cd / && exec env -i PATH=/usr/bin:/bin "${envs[@]}" "$@" "${AS_USER[@]}" "$BIN/shapematchd") 2>>"$log" &
    DPID=$!
    DAEMONS+=("$DPID")
    PORT=
    local i
    for ((i = 0; i < 200 * SLOW; i++)); do
        PORT=$(jq -r 'select(.event == "listening") | .port' "$log" 2>/dev/null | tail -1)
        [ -n "$PORT" ] && return 0
        kill -0 "$DPID" 2>/dev/null || break
        sleep 0.05
    done
    return 1
}
stop_env() {
    kill -TERM "$DPID" 2>/dev/null
    local i
    for ((i = 0; i < 300 * SLOW; i++)); do
        kill -0 "$DPID" 2>/dev/null || break
        sleep 0.05
    done
    kill -KILL "$DPID" 2>/dev/null
    wait "$DPID"
}
http_code() { curl -s --max-time 10 -o /dev/null -w '%{http_code}' "$@"; }

for kind in docker compose k8s systemd; do
    if [ ! -f "$W/env-$kind" ]; then
        not_ok "$kind: the deployment's environment is known"
        continue
    fi
    log=$W/daemon-$kind.log
    if ! start_env "$kind"; then
        not_ok "$kind: shapematchd starts with the deployment's environment" "$(cat "$log")" "$(cat "$W/env-$kind")"
        continue
    fi
    base=http://127.0.0.1:$PORT
    listening=$(jq -c 'select(.event == "listening")' "$log" | tail -1)
    want_workers=$(sed -n 's/^SHAPEMATCH_WORKERS=//p' "$W/env-$kind")
    want_auth=false
    grep -q '^SHAPEMATCH_TOKENS_FILE=' "$W/env-$kind" && want_auth=true
    if jq -e --arg w "${want_workers:-}" --argjson a "$want_auth" --arg s "$W/spool-$kind" \
        '(.workers | tostring) as $got | ($w == "" or $got == $w) and .auth == $a and .spool == $s' \
        <<<"$listening" >/dev/null; then
        ok "$kind: shapematchd starts with the deployment's environment${AS_USER:+ as uid 65534} (workers ${want_workers:-default}, auth $want_auth)"
    else
        not_ok "$kind: the daemon reports the deployment's settings" "$listening" "$(cat "$W/env-$kind")"
    fi
    h=$(http_code "$base/healthz")
    r=$(http_code "$base/readyz")
    if [ "$h" = 200 ] && [ "$r" = 200 ]; then ok "$kind: /healthz and /readyz answer 200"; else not_ok "$kind: /healthz and /readyz answer 200" "healthz $h, readyz $r"; fi
    auth=()
    if [ "$want_auth" = true ]; then
        token=$(grep -v '^[[:space:]]*#' "$W/tokens-$kind" | grep -m1 .)
        a=$(http_code "$base/v1/jobs")
        b=$(http_code -H "Authorization: Bearer $token" "$base/v1/jobs")
        if [ "$a" = 401 ] && [ "$b" = 200 ]; then ok "$kind: the example token file is enforced (401 without, 200 with it)"; else not_ok "$kind: token file enforced" "without $a, with $b"; fi
        auth=(-H "Authorization: Bearer $token")
    fi
    # a real job under the deployment's worker settings (threads, memory limit, timeouts)
    id=$(curl -s --max-time 30 "${auth[@]}" -F "template=@$EX/template.mesh" -F "target_mesh=@$EX/background.mesh.gz" \
        -F "target_sol=@$EX/background.sol.gz" -F 'params={"clamp": {"kind": "ball", "center": [0.5, 0.5], "radius": 0.04}, "max_iter": 3}' \
        "$base/v1/jobs" | jq -r '.jobID // empty')
    status=
    if [ -n "$id" ]; then
        curl -s --max-time $((60 * SLOW)) -N "${auth[@]}" "$base/v1/jobs/$id/events" >/dev/null
        status=$(curl -s "${auth[@]}" "$base/v1/jobs/$id" | jq -r .status)
    fi
    if [ "$status" = successful ]; then ok "$kind: a job runs to the end under the deployment's settings"; else not_ok "$kind: a job runs" "id=$id status=$status" "$(tail -5 "$log")"; fi
    if [ "$kind" = docker ] && [ -s "$W/healthcheck-cmd" ]; then
        # the image's HEALTHCHECK command, with the image's shell, on this daemon and on a closed port
        hc=$(cat "$W/healthcheck-cmd")
        env -i PATH=/usr/bin:/bin SHAPEMATCH_LISTEN=127.0.0.1:$PORT sh -c "$hc" >/dev/null 2>&1
        up=$?
        stop_env
        env -i PATH=/usr/bin:/bin SHAPEMATCH_LISTEN=127.0.0.1:$PORT sh -c "$hc" >/dev/null 2>&1
        down=$?
        if [ "$up" -eq 0 ] && [ "$down" -ne 0 ]; then ok "the image's HEALTHCHECK command passes on a live daemon, fails on a dead one"; else not_ok "HEALTHCHECK command" "live: $up, dead: $down" "$hc"; fi
    else
        stop_env
    fi
    rc=$?
    if [ "$rc" -eq 0 ] && ! grep -qE 'Sanitizer|runtime error' "$log" "$W/spool-$kind"/jobs/*/worker.log 2>/dev/null; then
        ok "$kind: SIGTERM stops the daemon cleanly (status 0)"
    else
        not_ok "$kind: SIGTERM stops the daemon cleanly" "status $rc" "$(tail -5 "$log")"
    fi
done
# the check can fail: a bad value in a deployment file stops the daemon at once
if start_env docker SHAPEMATCH_WORKERS=two; then
    not_ok "a bad SHAPEMATCH_WORKERS value is refused at start"
    stop_env
else
    wait "$DPID" 2>/dev/null
    if grep -q 'SHAPEMATCH_WORKERS' "$W/daemon-docker.log"; then ok "a bad SHAPEMATCH_WORKERS value is refused at start, naming the variable"; else not_ok "a bad value is refused naming the variable" "$(cat "$W/daemon-docker.log")"; fi
fi

# ============================ the unit's sandbox against what the daemon does
# (release programs, as installed; strace follows the daemon and its worker)
if [ "$VARIANT" != release ]; then
    skip "sandbox check runs in the release variant (the unit runs release programs)"
elif ! command -v strace >/dev/null || ! strace -f -o /dev/null true 2>/dev/null; then
    skip "strace is not usable here: sandbox check not run"
else
    state=$W/state
    mkdir -p "$state"
    # the unit's environment, %S (the state root) mapped to this folder
    senv=()
    while IFS= read -r line; do
        line=${line//%S/$state}
        case $line in SHAPEMATCH_LISTEN=*) line=SHAPEMATCH_LISTEN=127.0.0.1:0 ;; esac
        senv+=("$line")
    done <"$W/env-systemd"
    grep -q '^SHAPEMATCH_LISTEN=' "$W/env-systemd" || senv+=(SHAPEMATCH_LISTEN=127.0.0.1:0)
    spool=$(printf '%s\n' "${senv[@]}" | sed -n 's/^SHAPEMATCH_SPOOL=//p')
    log=$W/daemon-strace.log
    (cd / && exec env -i PATH=/usr/bin:/bin "${senv[@]}" strace -f -qq -o "$W/trace" \
        "$W/prefix/bin/shapematchd") 2>"$log" &
    SPID=$!
    DAEMONS+=("$SPID")
    port=
    for ((i = 0; i < 400; i++)); do
        port=$(jq -r 'select(.event == "listening") | .port' "$log" 2>/dev/null | tail -1)
        [ -n "$port" ] && break
        sleep 0.05
    done
    base=http://127.0.0.1:$port
    id=$(curl -s --max-time 30 -F "template=@$EX/template.mesh" -F "target_mesh=@$EX/background.mesh.gz" \
        -F "target_sol=@$EX/background.sol.gz" -F 'params={"clamp": {"kind": "ball", "center": [0.5, 0.5], "radius": 0.04}, "max_iter": 3}' \
        "$base/v1/jobs" | jq -r '.jobID // empty')
    curl -s --max-time 60 -N "$base/v1/jobs/$id/events" >/dev/null
    for path in "v1/jobs/$id" "v1/jobs/$id/results/mesh?format=vtu" "v1/jobs/$id/results/history" metrics readyz; do
        curl -s --max-time 10 --compressed -o /dev/null "$base/$path"
    done
    curl -s --max-time 10 -X DELETE -o /dev/null "$base/v1/jobs/$id"
    # the daemon, not strace (which does not pass signals on): strace ends with it
    kill -TERM $(pgrep -P "$SPID" -x shapematchd) 2>/dev/null
    for ((i = 0; i < 400; i++)); do kill -0 "$SPID" 2>/dev/null || break; sleep 0.05; done
    kill -KILL "$SPID" 2>/dev/null
    wait "$SPID"
    # one line per call: "<unfinished ...>" joined with its "resumed>" rest
    awk '{
        pid = $1
        if (match($0, /<\.\.\. [a-z_0-9]+ resumed>/)) { print part[pid] substr($0, RSTART + RLENGTH); delete part[pid] }
        else if (sub(/ <unfinished \.\.\.>$/, "")) part[pid] = $0
        else print
    }' "$W/trace" >"$W/trace.joined"
    src=$W/units/shapematchd.service
    if [ -z "$id" ] || [ ! -s "$W/trace" ]; then
        not_ok "a job ran under strace with the unit's environment" "id=$id" "$(tail -5 "$log")"
    else
        # system calls: allowed by the unit's SystemCallFilter lines
        expand() { # a group or call -> calls
            local s
            systemd-analyze syscall-filter "$1" 2>/dev/null | awk 'NR > 1 && !/^ *#/ && NF { print $1 }' |
                while read -r s; do case $s in @*) expand "$s" ;; *) echo "$s" ;; esac; done
        }
        : >"$W/allow"
        : >"$W/deny"
        while IFS= read -r f; do
            if [[ $f == "~"* ]]; then for g in ${f#\~}; do expand "$g" >>"$W/deny"; done
            else for g in $f; do expand "$g" >>"$W/allow"; done; fi
        done < <(sed -n 's/^SystemCallFilter=//p' "$src")
        sort -u -o "$W/allow" "$W/allow"
        sort -u -o "$W/deny" "$W/deny"
        awk '{ l = $0; sub(/^[0-9]+ +/, "", l); if (match(l, /^[a-z_0-9]+\(/)) print substr(l, 1, RLENGTH - 1) }' \
            "$W/trace" | sort -u >"$W/used"
        blocked=$( (comm -23 "$W/used" "$W/allow"; comm -12 "$W/used" "$W/deny") | sort -u | tr '\n' ' ')
        if [ -s "$W/allow" ] && [ -z "$blocked" ]; then
            ok "every system call of the daemon and its worker ($(wc -l <"$W/used") distinct) passes the unit's SystemCallFilter"
        else
            not_ok "every system call passes the unit's SystemCallFilter" "blocked: $blocked"
        fi
        fams=$(grep -oE 'socket\((AF_[A-Z0-9]+)' "$W/trace" | sed 's/socket(//' | sort -u | tr '\n' ' ')
        allowed_fams=" $(sed -n 's/^RestrictAddressFamilies=//p' "$src") "
        bad=
        for f in $fams; do [[ $allowed_fams == *" $f "* ]] || bad="$bad $f"; done
        check "socket families used (${fams:-none}) are in RestrictAddressFamilies" test -z "$bad"
        # ProcSubset=pid: only the processes' own /proc entries.  Two
        # exceptions, both reads that fail harmlessly where the unit hides
        # them: glibc reads /proc/sys/vm/overcommit_memory when it shrinks
        # a thread's malloc arena (OpenMP threads allocate) and keeps the
        # memory mapped without it; the worker's thread policy reads
        # /proc/loadavg for the idle cores (sm_job_idle_cores) and without
        # it counts none idle (one thread below 100k elements).
        procs=$(grep -oE '"/proc/[^"]*"' "$W/trace" | tr -d '"' | grep -vE '^/proc/(self|thread-self|[0-9]+)(/|$)' |
            grep -vxE '/proc/sys/vm/overcommit_memory|/proc/loadavg' | sort -u | tr '\n' ' ')
        check "only /proc/self entries are read (ProcSubset=pid)${procs:+: not $procs}" test -z "$procs"
        # MemoryDenyWriteExecute=yes: no mapping both writable and executable
        wx=$(grep -E '(mmap|mprotect|pkey_mprotect)\(.*(PROT_WRITE\|PROT_EXEC|PROT_EXEC\|PROT_WRITE|PROT_READ\|PROT_WRITE\|PROT_EXEC)' \
            "$W/trace.joined" | head -3)
        check "no writable and executable memory (MemoryDenyWriteExecute)" test -z "$wx"
        [ -z "$wx" ] || echo "#   $wx"
        # ProtectSystem=strict: files are written in the state directory only
        # (attempts that fail, e.g. mkdir -p meeting /var, change nothing)
        writes=$(grep -E 'open(at)?\(.*O_(WRONLY|RDWR|CREAT)|mkdir(at)?\(|rename(at2?)?\(|unlink(at)?\(|rmdir\(' "$W/trace.joined" |
            grep -v '= -1 E' |
            grep -oE '"/[^"]*"' | tr -d '"' | grep -vE "^($state|/dev/null|/dev/tty)(/|\$)" | sort -u | tr '\n' ' ')
        check "every file written or created is under the StateDirectory${writes:+: not $writes}" test -z "$writes"
    fi
fi

[ "$failed" -eq 0 ]
