#!/usr/bin/env bash
# TAP tests of the installed tree (`make install DESTDIR=... PREFIX=...`,
# the release build; the asan variant skips, the tree being the same):
#   - every part is there: programs, libshapematch.so.MAJOR (+ links and
#     the archive), libshapematch_job.so.MAJOR, <shapematch.h> with every
#     public header, <shapematch_job.h>, shapematch.pc, both man pages, the
#     Python package; nothing outside PREFIX without UNITDIR;
#   - readelf: the SONAMEs; nm -D: libshapematch.so exports exactly the
#     functions of the public headers (tests/build/exports.sh --list) and
#     libshapematch_job.so only sm_run_*, nothing without the sm_ prefix;
#   - examples/c/match.c built with `pkg-config --cflags --libs shapematch`
#     against the tree, run on examples/2d: the vertices of `shapematch
#     run`'s result.mesh; a C++ compiler and -Wall -Wextra -Werror accept
#     the headers too;
#   - the Python package from the tree finds its libraries by itself;
#   - man -l renders shapematch(1) with every command and every parameter
#     flag of the table, and shapematchd(8) with every daemon setting, both
#     with an EXAMPLES section;
#   - LICENSE and THIRD-PARTY in share/doc/shapematch, and THIRD-PARTY
#     naming every library the installed ELF files need (and libcurl);
#   - make uninstall leaves nothing.
set -u
ROOT=${SM_ROOT:-$(cd "$(dirname "$0")/../.." && pwd)}
source "$ROOT/tests/lib/tap.sh"
if [ "${SM_VARIANT:-release}" != release ]; then
    skip "the installed tree is the release build (checked in the release variant)"
    exit 0
fi
REL=$ROOT/build/release
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
umake() { env -u MAKEFLAGS -u MFLAGS -u MAKELEVEL make --no-print-directory -C "$ROOT" "$@"; }
PREFIX=/opt/sm
D=$W/dest
T=$D$PREFIX

if umake -s -o release install DESTDIR="$D" PREFIX="$PREFIX" >"$W/install.out" 2>&1; then
    ok "make install DESTDIR=... PREFIX=$PREFIX"
else
    not_ok "make install DESTDIR=... PREFIX=$PREFIX" "$(cat "$W/install.out")"
    exit 1
fi
outside=$(cd "$D" && find . -mindepth 1 -not -path "./opt" -not -path "./opt/sm" -not -path "./opt/sm/*")
if [ -z "$outside" ]; then ok "nothing outside PREFIX without UNITDIR"; else not_ok "nothing outside PREFIX" "$outside"; fi

missing=
for f in bin/shapematch bin/shapematchd bin/shapematch-worker lib/libshapematch.so.0.1.0 \
    lib/libshapematch.so.0 lib/libshapematch.so lib/libshapematch.a lib/libshapematch_job.so.0 \
    lib/libshapematch_job.so include/shapematch.h include/shapematch_job.h \
    lib/pkgconfig/shapematch.pc share/man/man1/shapematch.1 share/man/man8/shapematchd.8 \
    lib/python3/dist-packages/shapematch/__init__.py; do
    [ -e "$T/$f" ] || missing="$missing $f"
done
for h in "$ROOT"/core/include/shapematch/*.h; do
    cmp -s "$h" "$T/include/shapematch/$(basename "$h")" || missing="$missing include/shapematch/$(basename "$h")"
    grep -qx "#include <shapematch/$(basename "$h")>" "$T/include/shapematch.h" ||
        missing="$missing (shapematch.h does not include $(basename "$h"))"
done
if [ -z "$missing" ]; then ok "the tree holds the programs, libraries, headers, .pc, man pages, Python package"
else not_ok "the tree holds every part" "missing:$missing"; fi

# ---------------------------------------------------------------- ELF
for l in libshapematch libshapematch_job; do
    so=$(readelf -d "$T/lib/$l.so.0" | sed -n 's/.*(SONAME).*\[\(.*\)\]/\1/p')
    if [ "$so" = "$l.so.0" ]; then ok "readelf: $l SONAME $so"; else not_ok "readelf: $l SONAME" "got '$so'"; fi
done
# defined dynamic symbols, without the version nodes (type A)
dsyms() { nm -D --defined-only "$1" | awk '$2 != "A" { sub(/@.*/, "", $3); print $3 }' | LC_ALL=C sort -u; }
exp=$(dsyms "$T/lib/libshapematch.so.0")
want=$(CC=${CC:-cc} "$ROOT/tests/build/exports.sh" --list)
if [ -n "$want" ] && [ "$exp" = "$want" ]; then
    ok "libshapematch.so exports exactly the $(printf '%s\n' "$want" | wc -l) functions of the public headers"
else
    not_ok "libshapematch.so exports exactly the public headers' functions" \
        "$(diff <(printf '%s\n' "$want") <(printf '%s\n' "$exp") | head -20)"
fi
foreign=$( { printf '%s\n' "$exp"; dsyms "$T/lib/libshapematch_job.so.0"; } | grep -v '^sm_' || true)
jobx=$(dsyms "$T/lib/libshapematch_job.so.0" | grep -v '^sm_run_' || true)
if [ -z "$foreign" ] && [ -z "$jobx" ]; then
    ok "no export without the sm_ prefix; libshapematch_job.so exports only sm_run_*"
else
    not_ok "no non-sm_ export" "$foreign" "$jobx"
fi
# the check can fail: a library built without the version script leaks
printf 'int sm_x(void);\nint helper(void) { return 1; }\nint sm_x(void) { return helper(); }\n' >"$W/leak.c"
cc -shared -fPIC -o "$W/leak.so" "$W/leak.c"
if dsyms "$W/leak.so" | grep -qx helper; then ok "... and the check sees a leaked non-sm_ symbol"
else not_ok "the export check sees a leaked symbol"; fi

# -------------------------------------------------- the C example via pkg-config
export PKG_CONFIG_PATH=$T/lib/pkgconfig PKG_CONFIG_SYSROOT_DIR=$D
flags=$(pkg-config --cflags --libs shapematch 2>&1)
if [ $? -eq 0 ] && [ "$(pkg-config --modversion shapematch)" = 0.1.0 ]; then
    ok "pkg-config --cflags --libs shapematch: $flags"
else
    not_ok "pkg-config knows shapematch" "$flags"
fi
# shellcheck disable=SC2086
if cc -std=c11 -Wall -Wextra -Werror -o "$W/match" "$ROOT/examples/c/match.c" $flags 2>"$W/cc.err"; then
    ok "examples/c/match.c builds against the installed tree with pkg-config's flags"
else
    not_ok "examples/c/match.c builds with pkg-config's flags" "$(cat "$W/cc.err")"
fi
printf '#include <shapematch.h>\n#include <shapematch_job.h>\nint main(int argc, char **argv) {\n  sm_error e; sm_error_clear(&e); (void)argv;\n  return argc > 5 ? sm_run_dim(0) + (int)sm_mesh_diameter(0, 0) : 0;\n}\n' >"$W/cxx.cpp"
# shellcheck disable=SC2086
if command -v c++ >/dev/null && c++ -Wall -Wextra -Werror -o "$W/cxx" "$W/cxx.cpp" $flags -lshapematch_job 2>"$W/cxx.err"; then
    ok "a C++ program includes <shapematch.h> and <shapematch_job.h> and links both libraries"
elif ! command -v c++ >/dev/null; then
    skip "no C++ compiler"
else
    not_ok "a C++ program includes the headers and links" "$(cat "$W/cxx.err")"
fi
E=$ROOT/examples/2d
if LD_LIBRARY_PATH=$T/lib "$W/match" "$E/template.mesh" "$E/background.mesh.gz" "$E/background.sol.gz" \
    0.5,0.5,0.04 "$W/ex.mesh" >"$W/ex.out" 2>"$W/ex.err" &&
    "$REL/shapematch" run --template "$E/template.mesh" --target-mesh "$E/background.mesh.gz" \
        --target-sol "$E/background.sol.gz" --clamp-ball 0.5,0.5,0.04 -q -o "$W/cli" >/dev/null 2>&1 &&
    diff <(awk '/^Vertices/ { v = 1; getline; next } v && NF == 3 { print; next } { v = 0 }' "$W/ex.mesh") \
        <(awk '/^Vertices/ { v = 1; getline; next } v && NF == 3 { print; next } { v = 0 }' "$W/cli/result.mesh") >/dev/null &&
    [ "$(awk '/^Vertices/ { getline; print; exit }' "$W/ex.mesh")" -gt 0 ]; then
    ok "the example (linked to libshapematch.so) gives shapematch run's vertices: $(cat "$W/ex.out")"
else
    not_ok "the example gives shapematch run's vertices" "$(cat "$W/ex.out" "$W/ex.err")"
fi
if ldd "$W/match" | grep -q "$T/lib/libshapematch.so.0" 2>/dev/null || LD_LIBRARY_PATH=$T/lib ldd "$W/match" | grep -q "$T/lib/libshapematch.so.0"; then
    ok "the example loads the installed libshapematch.so.0"
else
    not_ok "the example loads the installed libshapematch.so.0" "$(LD_LIBRARY_PATH=$T/lib ldd "$W/match")"
fi

# docs/c-api.md's program on the job API, as printed there
awk '/^```text$/ { on = 1; buf = ""; next } on && /^```$/ { on = 0; if (buf ~ /shapematch_job.h/) { printf "%s", buf; exit } next }
     on { buf = buf $0 "\n" }' "$ROOT/docs/c-api.md" >"$W/job.c"
mkdir -p "$W/jobrun"
ln -s "$ROOT/examples" "$W/jobrun/examples"
# shellcheck disable=SC2086
if cc -std=c11 -Wall -Wextra -Werror -o "$W/job" "$W/job.c" $flags -lshapematch_job 2>"$W/job.err" &&
    (cd "$W/jobrun" && LD_LIBRARY_PATH=$T/lib "$W/job" >"$W/job.out" 2>>"$W/job.err") &&
    grep -q '^finished: {' "$W/job.out" && [ -s "$W/jobrun/out-c/result.mesh" ] && [ -s "$W/jobrun/out-c/result.vtu" ]; then
    ok "docs/c-api.md's job program builds with pkg-config's flags + -lshapematch_job and runs examples/2d"
else
    not_ok "docs/c-api.md's job program builds and runs" "$(cat "$W/job.err")" "$(head -c 300 "$W/job.out" 2>/dev/null)"
fi

# ------------------------------------------------------------ Python
out=$(cd "$W" && env -u SHAPEMATCH_LIBDIR PYTHONPATH="$T/lib/python3/dist-packages" /usr/bin/python3 -c '
import shapematch, sys
d = shapematch.sdf(([[0, 0], [1, 0], [1, 1], [0, 1]], [[0, 1], [1, 2], [2, 3], [3, 0]]), [[0.5, 0.5]])
print(shapematch.__file__, d[0])' 2>&1)
if [ "$out" = "$T/lib/python3/dist-packages/shapematch/__init__.py -0.5" ]; then
    ok "the installed Python package loads its libraries from PREFIX/lib by itself"
else
    not_ok "the installed Python package loads its libraries" "$out"
fi

# ------------------------------------------------------------ licenses
# LICENSE and THIRD-PARTY installed as in the tree; every shared library an
# installed program or library names as NEEDED is on a "Linked:" line of
# THIRD-PARTY (or is one of ours), and so is the libcurl the client opens
L=$T/share/doc/shapematch
if cmp -s "$ROOT/LICENSE" "$L/LICENSE" && cmp -s "$ROOT/THIRD-PARTY" "$L/THIRD-PARTY" &&
    grep -q '^MIT License' "$L/LICENSE" && grep -q 'Copyright (c) 2026 shapematch developers' "$L/LICENSE"; then
    ok "LICENSE (MIT, shapematch developers 2026) and THIRD-PARTY installed in share/doc/shapematch"
else
    not_ok "LICENSE and THIRD-PARTY installed" "$(ls -l "$L" 2>&1)"
fi
linked=$(grep -E '^  (Linked|Loaded):' "$ROOT/THIRD-PARTY")
needed=$(for f in "$T"/bin/* "$T"/lib/libshapematch.so.0 "$T"/lib/libshapematch_job.so.0 \
    "$T"/lib/libshapematch_nglib.so.0; do
    readelf -d "$f" | sed -n 's/.*(NEEDED).*\[\(.*\)\]/\1/p'; done | LC_ALL=C sort -u)
unlisted=
for so in $needed libcurl.so.4; do
    case $so in libshapematch*) continue ;; esac
    grep -qF "$so" <<<"$linked" || unlisted="$unlisted $so"
done
# the check can fail: a library no entry names
grep -qF libfoo.so.1 <<<"$linked" && unlisted="$unlisted (the check matches anything)"
if [ -z "$unlisted" ] && [ "$(wc -w <<<"$needed")" -ge 10 ]; then
    ok "THIRD-PARTY names each of the $(wc -w <<<"$needed") libraries the installed programs link, and libcurl"
else
    not_ok "THIRD-PARTY names every linked library" "not listed:$unlisted" "needed: $needed"
fi
for so in $needed; do
    case $so in libshapematch*) continue ;; esac
    lic=$(awk -v so="$so" '/^  License:/ { lic = $0 } index($0, so) && /^  (Linked|Loaded):/ { print lic; exit }' "$ROOT/THIRD-PARTY")
    [ -n "$lic" ] || unlisted="$unlisted $so(no license line)"
done
if [ -z "$unlisted" ]; then ok "... each with its License: line"; else not_ok "each entry has a license" "$unlisted"; fi

# ------------------------------------------------------------ man
page1=$(MANWIDTH=80 man -l "$T/share/man/man1/shapematch.1" 2>"$W/man1.err" | col -b)
page8=$(MANWIDTH=80 man -l "$T/share/man/man8/shapematchd.8" 2>"$W/man8.err" | col -b)
if [ -n "$page1" ] && [ ! -s "$W/man1.err" ] && [ -n "$page8" ] && [ ! -s "$W/man8.err" ]; then
    ok "man -l renders shapematch(1) ($(printf '%s\n' "$page1" | wc -l) lines) and shapematchd(8) ($(printf '%s\n' "$page8" | wc -l) lines) without a warning"
else
    not_ok "man -l renders both pages" "$(cat "$W/man1.err" "$W/man8.err")"
fi
# what must be there: every command, every flag `run --help` lists, every
# daemon setting; a help text without its flag in the page is a generator bug
cmds=$("$REL/shapematch" --help | awk '/^Commands:/ { on = 1; next } on && /^$/ { on = 0 } on { print $1 }' | grep -v '^help$')
absent=
for c in $cmds; do grep -q "^   shapematch $c\$" <<<"$page1" || absent="$absent command:$c"; done
for f in $("$REL/shapematch" run --help | grep -oE '^  (-[a-z], )?--[a-z-]+' | grep -oE -- '--[a-z-]+'); do
    grep -qF -- "$f" <<<"$page1" || absent="$absent $f"
done
for f in $("$REL/shapematchd" --help | grep -oE '^  --[a-z-]+'); do
    grep -qF -- "$f" <<<"$page8" || absent="$absent shapematchd:$f"
done
nflags=$("$REL/shapematchd" --help | grep -cE '^  --[a-z-]+')
if [ -z "$absent" ] && [ -n "$cmds" ] && [ "$nflags" -gt 10 ]; then
    ok "the pages hold every command ($(echo $cmds | wc -w)), every run flag and every daemon setting ($nflags)"
else
    not_ok "the pages hold every command and flag" "absent:$absent"
fi

# the EXAMPLES of both pages: the Examples blocks of the --help texts
ex1=$(sed -n '/^EXAMPLES/,/^SEE ALSO/p' <<<"$page1")
ex8=$(sed -n '/^EXAMPLES/,/^SEE ALSO/p' <<<"$page8")
if grep -q 'shapematch run --template examples/2d/template.mesh' <<<"$ex1" &&
    grep -q 'shapematch submit --server' <<<"$ex1" && grep -q 'shapematchd --listen' <<<"$ex8" &&
    [ "$(grep -cE '^[[:space:]]+shapematch ' <<<"$ex1")" -ge 5 ]; then
    ok "both pages have an EXAMPLES section (shapematch(1): $(grep -cE '^[[:space:]]+shapematch ' <<<"$ex1") commands)"
else
    not_ok "EXAMPLES in both pages" "$ex1" "$ex8"
fi

# ------------------------------------------------------------ uninstall
umake -s uninstall DESTDIR="$D" PREFIX="$PREFIX" >"$W/uninstall.out" 2>&1
left=$(find "$D" -type f -o -type l)
if [ -z "$left" ]; then ok "make uninstall removes every file and link"; else not_ok "make uninstall removes everything" "$left"; fi

[ "$failed" -eq 0 ]
