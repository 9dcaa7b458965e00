#!/usr/bin/env bash
# The include graph of server/ (a file may only call what it includes, so
# this is its call graph too): printed as TAP comments, and checked for
# circles (tsort) and for the layering of the HTTP side: the reply layer
# (smd_reply) includes no route, table or dispatcher; the handlers
# (smd_routes, smd_results, smd_upload) include the reply layer and not
# the table or the dispatcher; the dispatcher (smd_http) includes the
# route table.  A module is a file name without .c/.h (smd_store.c and
# smd_store.h are one node).
source "$(dirname "$0")/../lib/tap.sh"
ROOT=${SM_ROOT:-$(cd "$(dirname "$0")/../.." && pwd)}
cd "$ROOT/server" || exit 1

# "from to" pairs, one per include of a server header by another module
headers=$(find . -name '*.h' -printf '%f\n')
edges=$(find . -name '*.[ch]' | while read -r f; do
    from=$(basename "${f%.*}")
    sed -nE 's/^[[:space:]]*#[[:space:]]*include[[:space:]]+"([a-z_]+\/)*([a-z_]+)\.h".*/\2/p' "$f" |
        while read -r to; do
            echo "$headers" | grep -qx "$to.h" && [ "$to" != "$from" ] && echo "$from $to"
        done
done | sort -u)
echo "$edges" | awk '{ deps[$1] = deps[$1] " " $2 } END { for (m in deps) print "# " m " ->" deps[m] }' | sort

if [ -n "$edges" ] && out=$(echo "$edges" | tsort 2>&1 >/dev/null) && [ -z "$out" ]; then
    ok "no include (or call) circle among server/ files"
else
    not_ok "no include circle among server/ files" "$out"
fi

includes() { echo "$edges" | grep -qx "$1 $2"; }
bad=""
for upper in smd_routes smd_results smd_upload smd_route_table smd_http shapematchd; do
    includes smd_reply "$upper" && bad+=" smd_reply->$upper"
done
if [ -z "$bad" ]; then
    ok "the reply layer includes nothing of the routes, the table or the dispatcher"
else
    not_ok "the reply layer is below the routes" "$bad"
fi
bad=""
for h in smd_routes smd_results smd_upload; do
    includes "$h" smd_reply || bad+=" $h-/->smd_reply"
    includes "$h" smd_route_table && bad+=" $h->smd_route_table"
    includes "$h" smd_http && bad+=" $h->smd_http"
done
if [ -z "$bad" ]; then
    ok "the handlers include the reply layer, not the table or the dispatcher"
else
    not_ok "handlers sit between the reply layer and the table" "$bad"
fi
if includes smd_http smd_route_table && ! includes smd_http smd_routes && ! includes smd_http smd_results; then
    ok "the dispatcher reaches the handlers through the route table only"
else
    not_ok "the dispatcher includes the route table (and no handler header)"
fi
# the state lives in one place: no module below the HTTP side includes it
bad=""
for low in smd_store smd_queue smd_util smd_log smd_metrics smd_config smd_auth; do
    for upper in smd_http smd_reply smd_routes smd_results smd_upload smd_route_table smd_pool smd_stream; do
        includes "$low" "$upper" && bad+=" $low->$upper"
    done
done
if [ -z "$bad" ]; then
    ok "store, queue, metrics, config, auth, log and util include nothing above them"
else
    not_ok "the lower modules stay below" "$bad"
fi
# the job engine holds no connection: jobs/ reaches nothing of http/ or
# api/ (nor libmicrohttpd), not even through another header (cc -M
# follows every include)
bad=""
for f in jobs/*.c jobs/*.h; do
    if ! deps=$(cc -std=c11 -D_GNU_SOURCE -I "$ROOT/core/include" -I "$ROOT/proto" -I . -M -x c "$f" 2>&1); then
        bad+=" $f: cc -M failed: $deps"
        continue
    fi
    deps=$(echo "$deps" | tr ' \\' '\n\n' | grep -E '^(http|api)/.*\.h$|/microhttpd\.h$')
    [ -n "$deps" ] && bad+=" $f: $(echo $deps)"
done
if [ -z "$bad" ] && ls jobs/*.c >/dev/null 2>&1; then
    ok "the job engine (jobs/) includes nothing of http/ or api/, directly or not"
else
    not_ok "the job engine includes no HTTP or API header" "$bad"
fi
echo "1..$n"
