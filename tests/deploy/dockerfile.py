#!/usr/bin/env python3
"""Builds a Dockerfile without a Docker engine, for tests/deploy/docker_build.sh.

Each stage's FROM gets a fresh root extracted from one mmdebstrap tarball
(a minimal Debian bookworm, what debian:bookworm and debian:bookworm-slim
are); RUN steps run in it with chroot (/bin/sh -c, the stage's ENV,
WORKDIR and USER, /proc mounted, the host's resolv.conf as Docker gives
it); COPY copies from the build context (minus the .dockerignore
patterns) or, with --from, from an earlier stage's root.  Only the
instructions our Dockerfile uses are interpreted: FROM, RUN (shell form),
COPY, WORKDIR, ENV, USER; EXPOSE, VOLUME, HEALTHCHECK, STOPSIGNAL,
ENTRYPOINT, CMD and LABEL are recorded; anything else (ADD, ARG, SHELL,
ONBUILD, RUN in exec form, COPY --chown, ...) stops the build with its
line number.

Usage: dockerfile.py DOCKERFILE CONTEXT WORKDIR TARBALL
Writes WORKDIR/<stage>/ (one root per stage), WORKDIR/image.json (the
last stage: root, user, env, entrypoint, healthcheck, expose, volume)
and prints one line per step with its duration.
"""
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import tarfile
import time

SUPPORTED_IMAGES = ("debian:bookworm", "debian:bookworm-slim")
DEFAULT_PATH = "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"
RECORDED = ("EXPOSE", "VOLUME", "HEALTHCHECK", "STOPSIGNAL", "ENTRYPOINT", "CMD", "LABEL")


class BuildError(Exception):
    pass


def instructions(path):
    """(line number, INSTRUCTION, arguments) with continuations joined and
    comment lines (also inside a continued instruction) left out."""
    out, buf, start = [], "", 0
    for n, raw in enumerate(open(path), 1):
        line = raw.rstrip("\n")
        if line.strip().startswith("#") or (not buf and not line.strip()):
            continue
        if not buf:
            start = n
        if line.endswith("\\"):
            buf += line[:-1] + " "
            continue
        buf += line
        word, _, rest = buf.strip().partition(" ")
        out.append((start, word.upper(), rest.strip()))
        buf = ""
    if buf:
        raise BuildError("line %d: the file ends inside a continued instruction" % start)
    return out


def ignore_patterns(dockerfile, context):
    """BuildKit reads <Dockerfile>.dockerignore first, then CONTEXT/.dockerignore."""
    for p in (dockerfile + ".dockerignore", os.path.join(context, ".dockerignore")):
        if os.path.exists(p):
            pats = [l.strip() for l in open(p) if l.strip() and not l.strip().startswith("#")]
            for q in pats:
                if q.startswith("!"):
                    raise BuildError("%s: exception patterns (%s) are not supported" % (p, q))
            return [q.strip("/") for q in pats]
    return []


def pattern_regex(pat):
    """A .dockerignore pattern as a regex on a relative path: * and ? stay
    inside a component, **/ spans any number of them."""
    out, i = "", 0
    while i < len(pat):
        if pat.startswith("**/", i):
            out, i = out + "(?:.*/)?", i + 3
        elif pat.startswith("**", i):
            out, i = out + ".*", i + 2
        elif pat[i] == "*":
            out, i = out + "[^/]*", i + 1
        elif pat[i] == "?":
            out, i = out + "[^/]", i + 1
        else:
            out, i = out + re.escape(pat[i]), i + 1
    return re.compile(out + r"(?:/.*)?\Z")  # a matched folder excludes what it holds


def ignored(rel, regexes):
    return any(r.match(rel) for r in regexes)


def within(root, path):
    """root/path, path taken as absolute inside root."""
    full = os.path.normpath(os.path.join(root, path.lstrip("/")))
    if not (full == root or full.startswith(root + os.sep)):
        raise BuildError("%s leaves the root" % path)
    return full


class Stage:
    def __init__(self, name, image, root):
        self.name, self.image, self.root = name, image, root
        self.env = {"PATH": DEFAULT_PATH}
        self.workdir, self.user = "/", "0:0"
        self.meta = {}


class Builder:
    def __init__(self, dockerfile, context, workdir, tarball):
        self.dockerfile, self.context = os.path.abspath(dockerfile), os.path.abspath(context)
        self.workdir, self.tarball = os.path.abspath(workdir), tarball
        self.stages, self.mounts = [], []
        self.ignore = [pattern_regex(p) for p in ignore_patterns(self.dockerfile, self.context)]

    # ---- the instructions ----

    def from_(self, n, args):
        toks = args.split()
        if len(toks) not in (1, 3) or (len(toks) == 3 and toks[1].upper() != "AS"):
            raise BuildError("line %d: FROM IMAGE [AS NAME] expected, got %r" % (n, args))
        image = toks[0]
        if image not in SUPPORTED_IMAGES:
            raise BuildError("line %d: FROM %s: only %s are made here (mmdebstrap minbase)"
                             % (n, image, ", ".join(SUPPORTED_IMAGES)))
        name = toks[2] if len(toks) == 3 else str(len(self.stages))
        root = os.path.join(self.workdir, "stage-%d-%s" % (len(self.stages), name))
        os.makedirs(root)
        with tarfile.open(self.tarball) as t:  # a fresh root for every stage
            t.extractall(root, numeric_owner=True)
        shutil.copyfile("/etc/resolv.conf", os.path.join(root, "etc/resolv.conf"))
        self.stages.append(Stage(name, image, root))

    def stage(self, n):
        if not self.stages:
            raise BuildError("line %d: an instruction before the first FROM" % n)
        return self.stages[-1]

    def workdir_(self, n, args):
        s = self.stage(n)
        s.workdir = os.path.normpath(os.path.join(s.workdir, args))
        os.makedirs(within(s.root, s.workdir), exist_ok=True)

    def env_(self, n, args):
        s = self.stage(n)
        toks = shlex.split(args)
        if toks and "=" not in toks[0]:  # the old form: ENV KEY VALUE...
            s.env[toks[0]] = args.split(None, 1)[1] if len(toks) > 1 else ""
            return
        for tok in toks:
            k, eq, v = tok.partition("=")
            if not eq:
                raise BuildError("line %d: ENV %r is not KEY=VALUE" % (n, tok))
            s.env[k] = v

    def user_(self, n, args):
        s = self.stage(n)
        if not re.fullmatch(r"\d+(:\d+)?", args):
            raise BuildError("line %d: USER %s: only numeric UID[:GID] is supported" % (n, args))
        s.user = args if ":" in args else args + ":" + args

    def run_(self, n, args):
        s = self.stage(n)
        if args.startswith("["):
            raise BuildError("line %d: RUN in exec form is not supported" % n)
        if args.startswith("--"):
            raise BuildError("line %d: RUN options (%s) are not supported" % (n, args.split()[0]))
        proc = within(s.root, "/proc")
        os.makedirs(proc, exist_ok=True)
        if not os.path.ismount(proc):
            subprocess.run(["mount", "-t", "proc", "proc", proc], check=True)
            self.mounts.append(proc)
        env = dict(s.env)
        env.setdefault("HOME", "/root")
        ca = self.host_ca(s, env)
        cmd = ["chroot", "--userspec=" + s.user, s.root, "/bin/sh", "-c",
               "cd %s && %s" % (shlex.quote(s.workdir), args)]
        try:
            rc = subprocess.run(cmd, env=env).returncode
        finally:
            if ca:
                os.unlink(ca)
        if rc != 0:
            raise BuildError("line %d: RUN exited with %d: %s" % (n, rc, args[:200]))

    def host_ca(self, s, env):
        """A host behind a TLS-intercepting proxy (as this CI machine is)
        names its CA bundle in NODE_EXTRA_CA_CERTS: the RUN step gets a
        copy, like a build secret (npm ci reaches the registry through
        that proxy), removed after the step so no image keeps it.  None
        when the host sets none.  Returns the copy's path on the host."""
        bundle = os.environ.get("NODE_EXTRA_CA_CERTS")
        if not bundle or not os.path.isfile(bundle):
            return None
        inside = "/tmp/.host-ca-bundle.crt"
        copy = within(s.root, inside)
        os.makedirs(os.path.dirname(copy), exist_ok=True)
        shutil.copyfile(bundle, copy)
        os.chmod(copy, 0o644)
        env["NODE_EXTRA_CA_CERTS"] = inside
        env["npm_config_cafile"] = inside
        return copy

    def copy_(self, n, args):
        s = self.stage(n)
        toks = shlex.split(args)
        src_root, ignore = self.context, self.ignore
        while toks and toks[0].startswith("--"):
            opt = toks.pop(0)
            if not opt.startswith("--from="):
                raise BuildError("line %d: COPY %s is not supported" % (n, opt))
            ref = opt[len("--from="):]
            named = [t for t in self.stages[:-1] if t.name == ref]
            if not named:
                raise BuildError("line %d: COPY --from=%s: no earlier stage of that name" % (n, ref))
            src_root, ignore = named[-1].root, []
        if toks and toks[0].startswith("["):
            raise BuildError("line %d: COPY in JSON form is not supported" % n)
        if len(toks) < 2:
            raise BuildError("line %d: COPY SRC... DEST expected" % n)
        *srcs, dest = toks
        dest_abs = os.path.join(s.workdir, dest)
        to_dir = dest.endswith("/") or dest in (".", "./") or len(srcs) > 1
        for src in srcs:
            if any(c in src for c in "*?["):
                raise BuildError("line %d: COPY wildcards (%s) are not supported" % (n, src))
            self.copy_one(n, src_root, ignore, src, s.root, dest_abs, to_dir)

    def copy_one(self, n, src_root, ignore, src, root, dest_abs, to_dir):
        path = within(src_root, src)
        if not os.path.lexists(path):
            raise BuildError("line %d: COPY %s: not found" % (n, src))
        if os.path.isdir(path) and not os.path.islink(path):
            # a folder: its content goes into DEST, minus the ignored paths
            base = os.path.relpath(path, src_root)
            for dirpath, dirnames, filenames in os.walk(path):
                reldir = os.path.relpath(dirpath, path)
                for d in list(dirnames):
                    rel = os.path.normpath(os.path.join(base, reldir, d))
                    if ignore and ignored(rel, ignore):
                        dirnames.remove(d)
                target_dir = within(root, os.path.join(dest_abs, reldir))
                os.makedirs(target_dir, exist_ok=True)
                for f in filenames:
                    rel = os.path.normpath(os.path.join(base, reldir, f))
                    if not (ignore and ignored(rel, ignore)):
                        shutil.copy2(os.path.join(dirpath, f), os.path.join(target_dir, f),
                                     follow_symlinks=False)
            return
        rel = os.path.relpath(path, src_root)
        if ignore and ignored(rel, ignore):
            raise BuildError("line %d: COPY %s: excluded by .dockerignore" % (n, src))
        target = within(root, os.path.join(dest_abs, os.path.basename(path)) if to_dir else dest_abs)
        os.makedirs(os.path.dirname(target), exist_ok=True)
        shutil.copy2(path, target)

    # ---- the whole file ----

    def build(self):
        steps = instructions(self.dockerfile)
        for n, word, args in steps:  # refuse before doing anything
            if word not in ("FROM", "RUN", "COPY", "WORKDIR", "ENV", "USER") + RECORDED:
                raise BuildError("line %d: %s is not supported by this builder" % (n, word))
        try:
            for n, word, args in steps:
                t0 = time.monotonic()
                if word in RECORDED:
                    self.stage(n).meta[word] = args
                else:
                    getattr(self, word.lower() + "_")(n, args)
                print("# step line %d %s %s: %.1f s" % (n, word, args[:60], time.monotonic() - t0),
                      flush=True)
        finally:
            self.unmount()
        last = self.stages[-1]
        entry = json.loads(last.meta["ENTRYPOINT"]) if "ENTRYPOINT" in last.meta else []
        health = last.meta.get("HEALTHCHECK", "")
        m = re.search(r"\bCMD\s+(.*)$", health)
        image = {"root": last.root, "user": last.user, "env": last.env, "workdir": last.workdir,
                 "entrypoint": entry, "healthcheck": m.group(1) if m else "",
                 "expose": last.meta.get("EXPOSE", ""), "volume": last.meta.get("VOLUME", ""),
                 "stages": [s.name for s in self.stages]}
        with open(os.path.join(self.workdir, "image.json"), "w") as f:
            json.dump(image, f, indent=2)

    def unmount(self):
        for m in reversed(self.mounts):
            subprocess.run(["umount", m], check=False)
        self.mounts = []


def main():
    if len(sys.argv) != 5:
        print(__doc__, file=sys.stderr)
        return 2
    try:
        Builder(*sys.argv[1:]).build()
    except BuildError as e:
        print("dockerfile.py: %s: %s" % (sys.argv[1], e), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
