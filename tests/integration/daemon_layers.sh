#!/usr/bin/env bash
# The daemon's layers are its folders (server/README.md), and these path
# rules keep them apart.  Every rule reads where a file stands, never a
# list of file names, so a file added to a folder is checked as it lands:
#   - includes of the daemon's headers name their folder ("jobs/smd_jobs.h")
#   - jobs/ (the engine) includes nothing of http/, api/ or store/pg/ (the
#     spool, store/spool/, is the local replica below it, used by name)
#   - http/ includes nothing but base/ (it knows no handler, no backend)
#   - base/ includes no other folder
#   - only http/ includes <microhttpd.h>; only store/pg/ <libpq-fe.h>
#   - no include circle between folders
#   - no handler (api/) computes a warp or takes a lock
# The folder graph is printed as TAP comments.  The rules are also run on
# a small tree that breaks each of them once, and must fail there: a
# rule that cannot fail checks nothing.
source "$(dirname "$0")/../lib/tap.sh"
ROOT=${SM_ROOT:-$(cd "$(dirname "$0")/../.." && pwd)}

# "file folder kind target" per include of a file under $1:
#   kind "own": a header of the tree (target: its folder, "." for the top)
#   kind "bare": a quoted include of a header of the tree without a folder
#   kind "sys": <microhttpd.h> or <libpq-fe.h> (target: the header)
includes_of() {
    local root=$1 f dir inc
    (cd "$root" && find . -name '*.[ch]' | sed 's|^\./||' | sort) | while read -r f; do
        dir=$(dirname "$f")
        sed -nE 's/^[[:space:]]*#[[:space:]]*include[[:space:]]*([<"][^>"]+[>"]).*/\1/p' "$root/$f" |
            while read -r inc; do
                case $inc in
                '<microhttpd.h>' | '<libpq-fe.h>') echo "$f $dir sys ${inc:1:-1}" ;;
                \"*/*\")
                    inc=${inc:1:-1}
                    [ -f "$root/$inc" ] && echo "$f $dir own $(dirname "$inc")" ;;
                \"*\")
                    inc=${inc:1:-1}
                    [ -n "$(cd "$root" && find . -name "$inc" -print -quit)" ] &&
                        echo "$f $dir bare $inc" ;;
                esac
            done
    done
}

# Prints one line per broken rule ("rule: what"), nothing when all hold.
check_tree() {
    local edges
    edges=$(includes_of "$1")
    echo "$edges" | awk '
        $3 == "bare" { print "path: " $1 " includes \"" $4 "\" without its folder" }
        $3 == "own" && $2 == "jobs" && $4 ~ /^(http|api|store\/pg)(\/|$)/ {
            print "engine: " $1 " includes " $4 "/" }
        $3 == "own" && $2 == "http" && $4 != "http" && $4 != "base" {
            print "http: " $1 " includes " $4 "/" }
        $3 == "own" && $2 == "base" && $4 != "base" { print "base: " $1 " includes " $4 "/" }
        $3 == "sys" && $4 == "microhttpd.h" && $2 != "http" {
            print "mhd: " $1 " includes <microhttpd.h>" }
        $3 == "sys" && $4 == "libpq-fe.h" && $2 != "store/pg" {
            print "libpq: " $1 " includes <libpq-fe.h>" }'
    local folders circle
    folders=$(echo "$edges" | awk '$3 == "own" && $2 != $4 { print $2, $4 }' | sort -u)
    circle=$([ -n "$folders" ] && echo "$folders" | tsort 2>&1 >/dev/null)
    if [ -n "$circle" ]; then
        echo "circle: $(echo "$circle" | grep -v 'input contains a loop' | sed 's/^tsort: //' | tr '\n' ' ')"
    fi
}

# ---- the tree
echo "# folder -> folders it includes (server/)"
includes_of "$ROOT/server" | awk '$3 == "own" && $2 != $4 { print $2, $4 }' | sort -u |
    awk '{ d[$1] = d[$1] " " $2 } END { for (f in d) print "# " f " ->" d[f] }' | sort
broken=$(check_tree "$ROOT/server")
for rule in path engine http base mhd libpq circle; do
    what=$(echo "$broken" | grep "^$rule: " | sed "s/^$rule: //" | head -5 | tr '\n' ';')
    case $rule in
    path) name="includes of the daemon's headers name their folder" ;;
    engine) name="jobs/ includes nothing of http/, api/ or store/pg/" ;;
    http) name="http/ includes only base/ (no handler, no backend)" ;;
    base) name="base/ includes no other folder" ;;
    mhd) name="only http/ includes <microhttpd.h>" ;;
    libpq) name="only store/pg/ includes <libpq-fe.h>" ;;
    circle) name="no include circle between folders" ;;
    esac
    if [ -z "$what" ]; then ok "$name"; else not_ok "$name" "$what"; fi
done

# ---- the rules can fail: a tree that breaks each once
bad=$(mktemp -d "${TMPDIR:-/tmp}/sm-layers-XXXXXX")
trap 'rm -rf "$bad"' EXIT
mkdir -p "$bad"/{base,http,api,jobs,store/spool,store/pg}
touch "$bad"/base/b.h "$bad"/http/h.h "$bad"/api/a.h "$bad"/jobs/j.h "$bad"/store/spool/s.h \
    "$bad"/store/pg/p.h
printf '#include "a.h"\n#include "http/h.h"\n' >"$bad/base/b.c"          # path, base
printf '#include "store/pg/p.h"\n#include "store/spool/s.h"\n#include <microhttpd.h>\n' \
    >"$bad/jobs/j.c" # engine (the spool allowed), mhd
printf '#include "api/a.h"\n#include <libpq-fe.h>\n' >"$bad/http/h.c"    # http, libpq
printf '#include "http/h.h"\n' >"$bad/api/a.c"                            # with http -> api: circle
printf '#include <libpq-fe.h>\n' >"$bad/store/pg/p.c"                     # allowed
broken=$(check_tree "$bad")
missing=""
for rule in path engine http base mhd libpq circle; do
    echo "$broken" | grep -q "^$rule: " || missing+=" $rule"
done
extra=$(echo "$broken" | grep -c 'store/pg/p.c\|includes store/spool/')
if [ -z "$missing" ] && [ "$extra" = 0 ]; then
    ok "every rule fails on a tree that breaks it (and allows store/pg's libpq, the engine's spool)"
else
    not_ok "every rule fails on a tree that breaks it" "did not fire:$missing; false alarms: $extra"
fi
# the job engine holds no connection: jobs/ reaches nothing of http/ or
# api/ (nor libmicrohttpd), not even through another header (cc -M
# follows every include)
bad=""
for f in "$ROOT"/server/jobs/*.c "$ROOT"/server/jobs/*.h; do
    if ! deps=$(cc -std=c11 -D_GNU_SOURCE -I "$ROOT/core/include" -I "$ROOT/proto" -I "$ROOT/server" \
        -M -x c "$f" 2>&1); then
        bad+=" ${f#"$ROOT"/}: cc -M failed: $deps"
        continue
    fi
    deps=$(echo "$deps" | tr ' \\' '\n\n' | grep -E '/server/(http|api)/.*\.h$|/microhttpd\.h$')
    [ -n "$deps" ] && bad+=" ${f#"$ROOT"/}: $(echo $deps)"
done
if [ -z "$bad" ] && ls "$ROOT"/server/jobs/*.c >/dev/null 2>&1; then
    ok "the job engine (jobs/) includes nothing of http/ or api/, directly or not"
else
    not_ok "the job engine includes no HTTP or API header" "$bad"
fi
# A rule over the handlers' source (api/, and http/ where said): the
# calls it forbids, found by FINDER, must be none in the tree, and FINDER
# must fire on a file that breaks the rule (a rule that cannot fail
# checks nothing).  api_rule NAME FINDER BAD-LINE FILES...
api_rule() {
    local name=$1 finder=$2 line=$3 found fired handler
    shift 3
    found=$("$finder" "$@")
    handler=$(mktemp "${TMPDIR:-/tmp}/sm-layers-handler-XXXXXX")
    printf '%s\n' "$line" >"$handler"
    fired=$("$finder" "$handler")
    rm -f "$handler"
    if [ -z "$found" ] && [ -n "$fired" ]; then
        ok "$name"
    else
        not_ok "$name" "sites: $(echo $found | head -c 300); fires on a bad file: ${fired:-no}"
    fi
}
# no handler parses or computes a warp (issues 36, 37): api/ and http/
# call the job layer's use case (job/sm_job_warp.h) in a check child, never
# core's warp or a mesh, surface, field, image or points reader itself.
computes_warp() { # FILES...: the calls, one per line
    grep -nE '\b(sm_warp_[a-z_]+|sm_(mesh|surface|sol|image)_read[a-z_]*|sm_points_[a-z_]+)[[:space:]]*\(' "$@" \
        /dev/null | sed "s|^$ROOT/||"
}
api_rule "no handler computes a warp or reads a mesh (api/, http/ call the job layer in a check child)" \
    computes_warp 'static void h(void) { sm_warp_points(w, 0, 0, 1, x, y, 0, 0, 0); }' \
    "$ROOT"/server/api/*.c "$ROOT"/server/http/*.c
# the handlers take no lock of the engine (issue 36): srv->lock, the
# tokens' or any other mutex is taken by a use case of jobs/ (or http/'s
# smd_http_identify), never in api/, so the protocols under a lock are
# written once, beside the state they guard.  No site is allowed: a new
# one is a use case to add.
takes_lock() { # FILES...: the lock calls, one per line
    grep -nE '\bpthread_(mutex_(lock|trylock|timedlock)|rwlock_[a-z]*lock|cond_[a-z]*wait)[[:space:]]*\(' \
        "$@" /dev/null | sed "s|^$ROOT/||"
}
api_rule "no handler takes a lock (api/ calls the engine's use cases: jobs/smd_usecases.h, jobs/smd_follow.h)" \
    takes_lock 'static void h(smd_server *srv) { pthread_mutex_lock(&srv->lock); }' \
    "$ROOT"/server/api/*.c "$ROOT"/server/api/*.h
echo "1..$n"
