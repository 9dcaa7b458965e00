#!/usr/bin/env bash
# The help texts against the option tables and what the programs do:
#   - run --help and submit --help name every option of the parameter
#     table (test_params --markdown) and of their own flag tables
#     (client/args.c, client/cmd_submit.c), and run --help names no option
#     that run does not take;
#   - run and sdf list only the exit codes they can return;
#   - the run synopsis shows --target-surface; submit and sdf name the
#     formats read (Gmsh .msh, VTK, PLY);
#   - shapematch-worker --help and --version exit 0 and name no source
#     file; shapematchd --help points to the served /v1/openapi.yaml.
source "$(dirname "$0")/../lib/cli.sh"
BINDIR=$(dirname "$BIN")
cd "$WORK" || exit 1
"$BINDIR/tests/test_params" --markdown >table.md 2>/dev/null
grep -o '`--[a-z-]*' table.md | tr -d '`' | sort -u >param_flags
sed -n '/classify_run_flag/,/^}/p' "$ROOT/client/args.c" | grep -o '{"-[-a-z]*"' | tr -d '{"' |
    sort -u >run_flags
grep -o '{"--[a-z-]*", [01], SB_' "$ROOT/client/cmd_submit.c" | grep -o -- '--[a-z-]*' |
    sort -u >submit_flags
"$BIN" run --help >run.txt 2>&1
"$BIN" submit --help >submit.txt 2>&1
"$BIN" sdf --help >sdf.txt 2>&1
nflags=$(wc -l <param_flags)
check "the parameter table has its flags ($nflags)" test "$nflags" -ge 20
missing() { # FILE FLAGS...: the flags not in FILE's text
    local f=$1 out=""
    shift
    for x in "$@"; do grep -q -- "$x\b" "$f" || out="$out $x"; done
    echo "$out"
}
m=$(missing run.txt $(cat param_flags run_flags))
check "run --help names every option of the parameter table and of run's own${m:+ (missing:$m)}" \
    test -z "$m"
m=$(missing submit.txt $(cat param_flags submit_flags))
check "submit --help names every option of the parameter table and of submit's own${m:+ (missing:$m)}" \
    test -z "$m"
extra=""
for x in $(grep -o -- '--[a-z][a-z-]*' run.txt | sort -u); do
    grep -qx -- "$x" param_flags run_flags || [ "$x" = --help ] || extra="$extra $x"
done
check "run --help names no option run does not take${extra:+ (extra:$extra)}" test -z "$extra"
codes() { sed -n '/^Exit codes:/,$p' "$1" | grep -oE '^  [0-9]+ ' | tr -d ' ' | tr '\n' ' '; }
check "run --help lists the exit codes 0-5 and 10 only ($(codes run.txt))" \
    test "$(codes run.txt)" = "0 1 2 3 4 5 10 "
check "sdf --help lists the exit codes 0, 1, 2, 4 only ($(codes sdf.txt))" \
    test "$(codes sdf.txt)" = "0 1 2 4 "
check "submit --help lists the daemon's exit codes" grep -q '^  7 ' submit.txt
check "the run synopsis shows --target-surface" \
    sh -c "sed -n '1,/^\$/p' run.txt | grep -q -- '--target-surface S'"
check "submit --help: the template may be Gmsh .msh or VTK" \
    sh -c "grep -A2 -- '--template FILE' submit.txt | grep -q '.msh' && grep -A2 -- '--template FILE' submit.txt | grep -q '.vtu'"
check "submit and sdf --help name PLY among the surfaces" \
    sh -c "grep -q PLY submit.txt && grep -q PLY sdf.txt"
"$BINDIR/shapematch-worker" --help >worker.txt 2>&1
rc=$?
check "shapematch-worker --help exits 0 without source paths" \
    sh -c "[ $rc = 0 ] && grep -q 'JOB_DIR' worker.txt && ! grep -qE '[a-z_/]+\.[ch]\b' worker.txt"
check "shapematch-worker --version" sh -c "'$BINDIR/shapematch-worker' --version | grep -qE '^shapematch-worker [0-9]+\.'"
"$BINDIR/shapematchd" --help >daemon.txt 2>&1
check "shapematchd --help points to the served /v1/openapi.yaml" \
    sh -c "grep -q '/v1/openapi.yaml' daemon.txt && ! grep -q 'proto/openapi.yaml' daemon.txt"

# The examples that end `shapematch --help` and `shapematchd --help` (the
# man pages' EXAMPLES): the local ones run as written from a folder that
# has the tree's examples/ (their files made), and every option of the
# daemon ones is one of the command's own
"$BIN" --help >main.txt 2>&1
examples() { # HELP-FILE: each command of its Examples block on one line
    sed -n '/^Examples:$/,$p' "$1" | tail -n +2 | grep -v '^  #' |
        sed 's/^  //' | sed -e ':a' -e '/\\$/N; s/\\\n *//; ta'
}
examples main.txt >main.examples
mkdir -p ex && ln -sfn "$ROOT/examples" ex/examples
ran=0 failed_ex=
while IFS= read -r cmd; do
    case $cmd in *--server*) continue ;; esac
    (cd ex && PATH="$BINDIR:$PATH" bash -c "$cmd") >ex.out 2>&1 || failed_ex="$failed_ex [$cmd: $(tail -1 ex.out)]"
    ran=$((ran + 1))
done <main.examples
check "shapematch --help's local examples run as written ($ran: run, warp, sdf)" \
    sh -c "[ -z '$failed_ex' ] && [ $ran -ge 4 ] && [ -s ex/out-2d/result.mesh ] && [ -s ex/moved.csv ] && [ -s ex/distance.sol ]"
[ -z "$failed_ex" ] || echo "# $failed_ex"
bad_opts=
while IFS= read -r cmd; do
    sub=$(awk '{ print $2 }' <<<"$cmd")
    "$BIN" "$sub" --help >sub.txt 2>&1
    for o in $(grep -oE -- ' --[a-z-]+' <<<"$cmd"); do grep -q -- "$o\b" sub.txt || bad_opts="$bad_opts $sub$o"; done
done < <(grep -- '--server' main.examples)
examples daemon.txt >daemon.examples
for o in $(grep -oE -- ' --[a-z-]+' daemon.examples | sort -u); do
    grep -qE -- "^  $o( |$)" daemon.txt || bad_opts="$bad_opts shapematchd$o"
done
check "the daemon examples ($(grep -c -- --server main.examples) of shapematch, $(wc -l <daemon.examples) of shapematchd) use only options of their command" \
    sh -c "[ -z '$bad_opts' ] && [ $(wc -l <daemon.examples) -ge 3 ]"
[ -z "$bad_opts" ] || echo "# unknown options:$bad_opts"
