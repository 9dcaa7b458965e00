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
targets="mesh msh stl obj ply off template_surface vtk vtkxml sol params events payload sse headers multipart parts decimal job_file points nifti nrrd mha batch_list batch_request npy"
for t in $targets; do
    mkdir -p "$out/$t"
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
            *.nii|*.nii.gz) add nifti "$c" "$f"; continue ;;
            # the targets' prefixes give the first line
            *.nrrd|*.nhdr) tail -n +2 "$f" >"$out/nrrd/$c"; continue ;;
            *.mha|*.mhd) tail -n +2 "$f" >"$out/mha/$c"; continue ;;
            *.img) continue ;;
            *.obj) tail -n +1 "$f" >"$out/obj/$c"; continue ;;
            *.ply) tail -c +5 "$f" >"$out/ply/$c"; continue ;;
            *.off) tail -c +5 "$f" >"$out/off/$c"; continue ;;
            *.vtk) tail -c +24 "$f" >"$out/vtk/$c"; continue ;;
            *.vtu|*.vtp) add vtkxml "$c" "$f"; continue ;;
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
# the samples of every PLY, OFF and VTK encoding, without the targets' prefixes
for f in tests/data/formats/cells/*.ply; do tail -c +5 "$f" >"$out/ply/$(basename "$f")"; done
for f in tests/data/formats/cells/*.off; do tail -c +5 "$f" >"$out/off/$(basename "$f")"; done
for f in tests/data/formats/cells/*.off; do tail -c +5 "$f" >"$out/template_surface/$(basename "$f")"; done
for f in tests/data/formats/cells/*.vtk; do tail -c +24 "$f" >"$out/vtk/$(basename "$f")"; done
for f in tests/data/formats/cells/*.vt[up]; do add vtkxml "$(basename "$f")" "$f"; done
for f in tests/data/proto/params/good/*.json tests/data/proto/params/bad/*.json; do
    add params "$(basename "$(dirname "$f")")-$(basename "$f")" "$f" 000 001 002 003
done
for f in tests/data/proto/payload/*.smmesh; do add payload "$(basename "$f")" "$f" 000 001; done
