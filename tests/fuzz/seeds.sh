#!/usr/bin/env bash
# Fills build/fuzz/seeds/<target>/ with the seed corpus of each fuzz target:
# the hand-written seeds of tests/fuzz/seeds/<target>/ plus the matching
# files of tests/data (format samples, the malformed corpus, the params and
# payload cases), each under a unique name.  Targets whose input starts with
# a mode byte (params, events, payload) get the data files with each mode.
# Usage: tests/fuzz/seeds.sh OUTDIR
set -euo pipefail
cd "$(dirname "$0")/../.."
out=$1
rm -rf "$out"
mkdir -p "$out"/{mesh,msh,stl,obj,sol,params,events,payload,sse,headers,multipart,parts,decimal,job_file,landmarks}
for t in mesh msh stl obj sol params events payload sse headers multipart parts decimal job_file landmarks; do
    [ -d tests/fuzz/seeds/$t ] && cp tests/fuzz/seeds/$t/* "$out/$t/" 2>/dev/null || true
done
add() { # target name file [prefix-byte-octal...]
    local t=$1 name=$2 file=$3
    shift 3
    if [ $# -eq 0 ]; then
        cp "$file" "$out/$t/$name"
    else
        for b in "$@"; do
            { printf "\\$b"; cat "$file"; } >"$out/$t/$name-$b"
        done
    fi
}
for f in tests/data/formats/*.mesh; do add mesh "$(basename "$f")" "$f"; done
for d in tests/data/malformed/*/; do
    c=$(basename "$d")
    for f in "$d"input.*; do
        [ -f "$f" ] || continue
        case $f in
            *.stl|*.stl.gz) add stl "$c" "$f"; continue ;;
            *.obj) tail -n +1 "$f" >"$out/obj/$c"; continue ;;
        esac
        case $f in
            *.sol|*.solb|*.sol.gz|*.solb.gz) add sol "$c" "$f" ;;
            *) add mesh "$c" "$f" ;;
        esac
        # .msh cases also seed the .msh target, without its first line
        case $f in
            *.msh) tail -c +13 "$f" >"$out/msh/$c" ;;
        esac
    done
done
for f in tests/data/proto/params/good/*.json tests/data/proto/params/bad/*.json; do
    add params "$(basename "$(dirname "$f")")-$(basename "$f")" "$f" 000 001 002
done
for f in tests/data/proto/payload/*.smmesh; do add payload "$(basename "$f")" "$f" 000 001; done
