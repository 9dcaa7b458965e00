#!/usr/bin/env bash
# Regenerates the bundled examples from their .geo files and the analytic
# target shapes (examples/tools/shapes.h):
#
#   examples/{2d,3d}/template.mesh        Gmsh, plain Medit
#   examples/{2d,3d}/background.mesh.gz   Gmsh, Medit, gzip -n
#   examples/{2d,3d}/background.sol.gz    exact signed distance (tools/sdf)
#   examples/{2d,3d}/check.txt            sanity report (tools/check)
#   examples/{2d,3d}/clamp                the clamp ball, x,y[,z],r
#
# usage: examples/generate.sh [--verify] [2d] [3d]
#   (no case: both)  --verify regenerates into a temporary directory and
#   compares with the committed files byte for byte instead of replacing
#   them (exit 1 on any difference).
#
# The output is byte-for-byte reproducible with the same Gmsh version
# (recorded below and in examples/README.md; other versions mesh
# differently), single-threaded meshing and gzip -n (no name, no time).
set -euo pipefail

GMSH_VERSION_USED=4.8.4
GMSH=${GMSH:-gmsh}
CC=${CC:-cc}

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"

verify=0
cases=()
for arg in "$@"; do
    case $arg in
    --verify) verify=1 ;;
    2d | 3d) cases+=("$arg") ;;
    -h | --help)
        sed -n '2,18p' "$0" | sed 's/^# \{0,1\}//'
        exit 0
        ;;
    *)
        echo "generate.sh: unknown argument '$arg'" >&2
        exit 2
        ;;
    esac
done
[ ${#cases[@]} -gt 0 ] || cases=(2d 3d)

say() { printf 'generate.sh: %s\n' "$*"; }

gmsh_version=$("$GMSH" --version 2>&1 | tail -n 1)
if [ "$gmsh_version" != "$GMSH_VERSION_USED" ]; then
    say "warning: gmsh $gmsh_version, the committed files were made with" \
        "$GMSH_VERSION_USED: the meshes will not be byte-identical" >&2
fi

# The tools link with the release core library (Medit/sol readers and
# writers, mesh checks, P1 field).
say "building build/release/libshapematch.a and the tools"
make -s build/release/libshapematch.a
tools=build/release/examples
mkdir -p "$tools"
tool_flags=(-std=c11 -D_DEFAULT_SOURCE -D_GNU_SOURCE -Wall -Wextra -Werror -O2
    -I core/include -I examples/tools)
for tool in sdf check; do
    "$CC" "${tool_flags[@]}" "examples/tools/$tool.c" \
        build/release/libshapematch.a -lcholmod -lz -lm -o "$tools/$tool"
done

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# Gmsh writes "Dimension 3" with z = 0 for planar meshes, and its own
# geometric entity numbers as vertex references.  Rewrite the vertices:
# 2D files get "Dimension 2" and (x, y), and every vertex reference is 0
# (element and facet references, the physical tags, are kept as written).
# The coordinates are copied as text, so nothing is rounded.
tidy_medit() { # dim < gmsh.mesh > tidy.mesh
    awk -v dim="$1" '
        function fail(why) { print "tidy_medit: line " NR ": " why > "/dev/stderr"; bad = 1; exit 1 }
        /^ *Dimension *$/ { print; getline; print " " dim; next }
        /^ *Dimension +[0-9]+ *$/ { print " Dimension " dim; next }
        /^ *Vertices *$/ {
            print; getline; n = $1; print
            for (i = 0; i < n; i++) {
                if ((getline) <= 0) fail("truncated Vertices")
                if (NF != 4) fail("expected x y z ref")
                if (dim == 2) {
                    if ($3 + 0 != 0) fail("z is not 0 in a 2D mesh")
                    print " " $1 " " $2 " 0"
                } else {
                    print " " $1 " " $2 " " $3 " 0"
                }
            }
            next
        }
        { print }
        END { if (bad) exit 1 }'
}

mesh_with_gmsh() { # dim geo out.mesh
    # gmsh may report an error in a .geo file and still exit with 0
    if ! "$GMSH" "-$1" "$2" -format mesh -o "$tmp/gmsh.mesh" -v 2 \
        >"$tmp/gmsh.log" 2>&1 || grep -q 'Error' "$tmp/gmsh.log"; then
        cat "$tmp/gmsh.log" >&2
        say "gmsh failed on $2" >&2
        exit 1
    fi
    tidy_medit "$1" <"$tmp/gmsh.mesh" >"$3"
}

generate_case() { # case out_dir
    local c=$1 out=$2 dim target template clamp verify_res
    case $c in
    2d) dim=2 target=star2d template=disk2d clamp=0.5,0.5,0.04 verify_res=1024 ;;
    3d) dim=3 target=blob3d template=ball3d clamp=0.5,0.5,0.5,0.05 verify_res=40 ;;
    esac
    mkdir -p "$out"
    # the clamp ball, as --clamp-ball takes it (read by examples/demo.sh)
    printf '%s\n' "$clamp" >"$out/clamp"
    say "$c: template (gmsh)"
    mesh_with_gmsh $dim "examples/$c/template.geo" "$out/template.mesh"
    say "$c: background (gmsh)"
    mesh_with_gmsh $dim "examples/$c/background.geo" "$tmp/background.mesh"
    gzip -n -9 -c "$tmp/background.mesh" >"$out/background.mesh.gz"
    # First validate the distance tool where the answer is known in closed
    # form (the template shape), then compute the target's distance,
    # cross-checked against a brute-force search and against an
    # independent, much coarser discretisation of the target.
    say "$c: distance tool against the closed form ($template)"
    "$tools/sdf" --shape $template --mesh "$tmp/background.mesh" \
        --out "$tmp/exact.sol" --verify-exact 1e-12 --verify-brute 20
    say "$c: signed distance to $target"
    "$tools/sdf" --shape $target --mesh "$out/background.mesh.gz" \
        --out "$out/background.sol.gz" --verify-brute 100 \
        --verify-resolution $verify_res
    say "$c: sanity checks"
    # relative paths in the report, whatever out is
    (cd "$out" && "$root/$tools/check" --template template.mesh \
        --template-shape $template --background background.mesh.gz \
        --sol background.sol.gz --target-shape $target \
        --clamp $clamp) >"$out/check.txt" || {
        cat "$out/check.txt"
        say "$c: sanity checks FAILED" >&2
        exit 1
    }
    cat "$out/check.txt"
}

status=0
for c in "${cases[@]}"; do
    if [ $verify = 1 ]; then
        generate_case "$c" "$tmp/out/$c"
        for f in clamp template.mesh background.mesh.gz background.sol.gz check.txt; do
            if cmp -s "$tmp/out/$c/$f" "examples/$c/$f"; then
                say "$c/$f: identical"
            else
                say "$c/$f: DIFFERS from the committed file" >&2
                status=1
            fi
        done
    else
        generate_case "$c" "examples/$c"
    fi
done
exit $status
