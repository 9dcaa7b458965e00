#!/usr/bin/env bash
# The progress display of `shapematch run`: under a pseudo-terminal
# (script -qc) a bar toward the tolerance (log scale of the boundary
# error) or the iteration cap, with percentage, iteration rate and ETA,
# redrawn in place and ending at 100% when the cap is reached (the 3D
# example: its iterations are slow enough for several redraws); to a
# file, plain lines with no bar and no carriage return.
source "$(dirname "$0")/../lib/cli.sh"
EX=$ROOT/examples/2d
ARGS="--template $EX/template.mesh --target-mesh $EX/background.mesh.gz --target-sol $EX/background.sol.gz --clamp-ball $(tr -d ' \n' <"$EX/clamp")"
if ! command -v script >/dev/null; then echo "not ok - script(1) is installed"; exit 0; fi
# shellcheck disable=SC2086
EX3=$ROOT/examples/3d
ARGS3="--template $EX3/template.mesh --target-mesh $EX3/background.mesh.gz --target-sol $EX3/background.sol.gz --clamp-ball $(tr -d ' \n' <"$EX3/clamp")"
script -qec "$BIN run $ARGS3 --max-iter 20 -o $WORK/tty" /dev/null >"$WORK/tty.log" 2>&1
rc=$?
tr '\r' '\n' <"$WORK/tty.log" | sed 's/\x1b\[K//g' >"$WORK/tty.lines"
bars=$(grep -cE '^\[[#.]{20}\] +[0-9]+%  [0-9.]+ it/s  ETA [0-9]+s  iter [0-9]+ ' "$WORK/tty.lines")
mid=$(grep -E '^\[[#.]{20}\] +([1-9]|[1-9][0-9])%  ' "$WORK/tty.lines" | head -1)
last=$(grep -E '^\[' "$WORK/tty.lines" | tail -1)
if [ $rc -eq 0 ] && [ "$bars" -ge 2 ] && [ -n "$mid" ] && [ "${last#\[####################\] 100%}" != "$last" ] &&
    grep -q $'\r' "$WORK/tty.log"; then
    echo "ok - a terminal gets a bar redrawn in place ($bars draws), e.g. '${mid:0:60}', ending at 100%"
else
    echo "not ok - progress bar on a terminal (exit $rc, $bars bars)"; tail -c 600 "$WORK/tty.lines" | sed 's/^/# /'
fi
# shellcheck disable=SC2086
"$BIN" run $ARGS --max-iter 25 -o "$WORK/file" 2>"$WORK/file.err" >/dev/null
if ! grep -q $'\r' "$WORK/file.err" && ! grep -q '^\[' "$WORK/file.err" &&
    [ "$(grep -c '^iter ' "$WORK/file.err")" -ge 3 ]; then
    echo "ok - not a terminal: plain lines, no bar"
else
    echo "not ok - plain lines when not a terminal"; sed 's/^/# /' "$WORK/file.err"
fi
