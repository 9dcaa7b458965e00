#!/usr/bin/env bash
# TAP tests of the layers of core, proto and the client as path rules on
# the #include lines, so the rules follow the tree and cannot drift from
# it (the daemon's own rules are tests/integration/daemon_layers.sh):
#   - core never includes proto, client or server headers;
#   - only core/io/ includes core/io/ headers inside core (the model,
#     the field and the solver never call a reader: no circle
#     between the surface model and the readers);
#   - core/io/ includes nothing of core but the base helpers (sm_alloc.h)
#     and the public headers;
#   - proto/ (the wire contract) never includes proto/job/ (the job
#     runner, which stands on it);
#   - the client never includes server headers, nor the server client ones.
# Env: SM_ROOT (repo root).
set -u
ROOT=${SM_ROOT:-$(cd "$(dirname "$0")/../.." && pwd)}
cd "$ROOT" || exit 1
source tests/lib/tap.sh

# "file: included" for every quoted #include of the files given
includes() {
    grep -HoE '^[[:space:]]*#[[:space:]]*include[[:space:]]*"[^"]+"' "$@" 2>/dev/null |
        sed -E 's/:[[:space:]]*#[[:space:]]*include[[:space:]]*"/: /; s/"$//'
}

rule() { # DESC BAD-LINES
    if [ -z "$2" ]; then ok "$1"; else not_ok "$1" "$2"; fi
}

core_files=$(find core -name '*.[ch]' | sort)
io_files=$(find core/io -name '*.[ch]' | sort)
core_top=$(find core -maxdepth 1 -name '*.[ch]' | sort)
proto_files=$(find proto -maxdepth 1 -name '*.[ch]' | sort)
client_files=$(find client -name '*.[ch]' | sort)
server_files=$(find server -name '*.[ch]' | sort)

if [ -n "$core_files" ] && [ -n "$io_files" ] && [ -n "$proto_files" ] && [ -n "$client_files" ]; then
    ok "the folders hold sources (core, core/io, proto, client)"
else
    not_ok "the folders hold sources (core, core/io, proto, client)"
fi

# core: its own headers and the public ones only
proto_names=$(find proto -name '*.h' -printf '%f\n' | sort -u | paste -sd'|')
rule "core includes no proto header" \
    "$(includes $core_files | grep -E ": (job/)?($proto_names)$")"
rule "core includes no client or server header" \
    "$(includes $core_files | grep -E ': (smd_|cli\.h|args\.h|http\.h|remote\.h)')"

# the I/O family stays in its folder
rule "outside core/io, core includes no io/ header" \
    "$(includes $core_top | grep -E ': io/')"
rule "core/io includes only io/, sm_alloc.h and public headers" \
    "$(includes $io_files | grep -vE ': (io/|shapematch/|sm_alloc\.h$)')"
rule "core/io includes its own headers as io/..." \
    "$(includes $io_files | grep -E ': sm_' | grep -v ': sm_alloc\.h$')"

# proto: the contract below the job runner
rule "proto/ (the wire contract) never includes proto/job/" \
    "$(includes $proto_files | grep -E ': (job/|sm_job_)')"

# client and server do not include each other
rule "the client includes no server header" "$(includes $client_files | grep -E ': smd_')"
rule "the server includes no client header" \
    "$(includes $server_files | grep -E ': (cli|args|remote|daemon_ops|progress|fsutil|sse)\.h$')"

[ "$failed" -eq 0 ]
