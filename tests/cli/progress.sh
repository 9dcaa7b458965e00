#!/usr/bin/env bash
# The progress display of `shapematch run`: under a pseudo-terminal
# (script -qc) a bar toward the tolerance (log scale of the L2 norm that
# --tol-boundary compares) or the iteration cap, with percentage, the
# RMS distances, ETA and what else fits the terminal's width, redrawn in
# place and ending at 100% when the cap is reached (the 3D example: its
# iterations are slow enough for several redraws); 80 columns keep the
# line within 79, 200 show every field; to a file, plain lines with every
# named figure, no bar and no carriage return.
source "$(dirname "$0")/../lib/cli.sh"
EX=$ROOT/examples/2d
ARGS="--template $EX/template.mesh --target-mesh $EX/background.mesh.gz --target-sol $EX/background.sol.gz --clamp-ball $(tr -d ' \n' <"$EX/clamp")"
if ! command -v script >/dev/null; then echo "not ok - script(1) is installed"; exit 0; fi
# shellcheck disable=SC2086
EX3=$ROOT/examples/3d
ARGS3="--template $EX3/template.mesh --target-mesh $EX3/background.mesh.gz --target-sol $EX3/background.sol.gz --clamp-ball $(tr -d ' \n' <"$EX3/clamp")"
# an 80-column terminal (exit 0 or 10: twenty iterations may not cover the
# target; stty sets the pseudo-terminal's size, which the
# client reads with TIOCGWINSZ): every line fits in 79 columns and keeps
# the bar, the iteration, both RMS distances (result->target,
# target->result) and the ETA
script -qec "stty cols 80; $BIN run $ARGS3 --max-iter 20 -o $WORK/tty" /dev/null >"$WORK/tty.log" 2>&1
rc=$?
tr '\r' '\n' <"$WORK/tty.log" | sed 's/\x1b\[K//g' >"$WORK/tty.lines"
bars=$(grep -cE '^\[[#.]{10}\] +[0-9]+%  iter [0-9]+  r->t rms [0-9.e+-]+  t->r rms [0-9.e+-]+  .*ETA [0-9]+s' "$WORK/tty.lines")
mid=$(grep -E '^\[[#.]{10}\] +([1-9]|[1-9][0-9])%  ' "$WORK/tty.lines" | head -1)
last=$(grep -E '^\[' "$WORK/tty.lines" | tail -1)
long=$(grep -E '^\[' "$WORK/tty.lines" | awk 'length($0) > 79' | head -1)
if { [ $rc -eq 0 ] || [ $rc -eq 10 ]; } && [ "$bars" -ge 2 ] && [ -n "$mid" ] && [ "${last#\[##########\] 100%}" != "$last" ] &&
    grep -q $'\r' "$WORK/tty.log" && [ -z "$long" ]; then
    echo "ok - an 80-column terminal gets a bar redrawn in place ($bars draws) within 79 columns, e.g. '$mid', ending at 100%"
else
    echo "not ok - progress bar on an 80-column terminal (exit $rc, $bars bars, too long: '$long')"; tail -c 600 "$WORK/tty.lines" | sed 's/^/# /'
fi
# a wide terminal: every field, the max, the quality and the rate too
# (exit 10: not converged after 10 iterations)
script -qec "stty cols 200; $BIN run $ARGS3 --max-iter 10 --tol-boundary 1e-9 -o $WORK/wide" /dev/null >"$WORK/wide.log" 2>&1
rc=$?
wide=$(tr '\r' '\n' <"$WORK/wide.log" | sed 's/\x1b\[K//g' | grep -E '^\[[#]{0,20}[.]{0,20}\]' | tail -1)
if [ $rc -eq 10 ] && grep -qE '^\[[#.]{20}\] +[0-9]+%  iter [0-9]+  r->t rms [^ ]+  max [^ ]+  t->r rms [^ ]+  max [^ ]+  L2 [^ ]+ \(tol 1.0e-09\)  J [^ ]+  step [^ ]+  qmin [0-9.]+  [0-9.]+s  ETA [0-9]+s  [0-9.]+ it/s$' <<<"$wide" &&
    [ "${#wide}" -le 199 ]; then
    echo "ok - a 200-column terminal shows every field: '$wide'"
else
    echo "not ok - every field on a wide terminal (exit $rc)"; echo "# $wide"
fi
# shellcheck disable=SC2086
"$BIN" run $ARGS --max-iter 25 -o "$WORK/file" 2>"$WORK/file.err" >/dev/null
if ! grep -q $'\r' "$WORK/file.err" && ! grep -q '^\[' "$WORK/file.err" &&
    [ "$(grep -cE '^iter [0-9]+  result->target rms [^ ]+  max [^ ]+  target->result rms [^ ]+  max [^ ]+  p99 [^ ]+  relative [^ ]+  L2 [^ ]+  J ' "$WORK/file.err")" -ge 3 ]; then
    echo "ok - not a terminal: plain lines with every named figure, no bar"
else
    echo "not ok - plain lines when not a terminal"; sed 's/^/# /' "$WORK/file.err"
fi
