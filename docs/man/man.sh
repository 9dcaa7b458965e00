#!/usr/bin/env bash
# Writes the man pages shapematch(1) and shapematchd(8) from the programs'
# own --help texts, which are printed from their option tables (the
# commands table and client/args.c's parameter options read from
# sm_params_table; the daemon's settings table in server/base/smd_config.c):
# one source for --help, the man pages and, through test_params, the
# documentation's parameter table.
#
#   docs/man/man.sh BINDIR OUTDIR VERSION
#
# A help text becomes roff like this: "Usage:" lines the synopsis; a line
# ending in ':' at the margin a subsection; a line indented by two spaces
# a tagged paragraph (its tag is what comes before the first run of two
# spaces or more, or the whole line for the daemon's "  --flag META"),
# deeper lines its continuation; other lines filled text.  The
# "Examples:" block that ends `shapematch --help` and `shapematchd --help`
# becomes the EXAMPLES section: its "# ..." lines the text, the others
# commands set as they are.
set -euo pipefail
BIN=$1
OUT=$2
VERSION=$3
DATE=$(date -u -d "@${SOURCE_DATE_EPOCH:-$(date +%s)}" +%Y-%m-%d)
mkdir -p "$OUT"

# roff of one help text on stdin (its Usage block left out: the caller
# prints it in SYNOPSIS)
to_roff() {
    awk '
    function esc(s) { gsub(/\\/, "\\e", s); return s }
    function line(s) { s = esc(s); if (s ~ /^[.\047]/) s = "\\&" s; print s }
    function tag(s) { s = esc(s); gsub(/-/, "\\-", s); return s }
    BEGIN { usage = 1 }
    usage && /^(Usage:|      |$)/ { if ($0 == "") usage = 0; next }
    /^Examples:$/ { exit }
    { usage = 0 }
    /^$/ { print ".PP"; next }
    /^[A-Z][^ ].*:$/ { print ".SS \"" esc(substr($0, 1, length($0) - 1)) "\""; next }
    /^  [^ ]/ {
        s = substr($0, 3)
        i = match(s, /  +/)
        if (match(s, /^[0-9]+ /) && (i == 0 || RSTART + RLENGTH - 1 < i)) i = RLENGTH
        if (i > 0) { t = substr(s, 1, i - 1); d = substr(s, i); sub(/^ +/, "", d) }
        else { t = s; d = "" }
        print ".TP"; print "\\fB" tag(t) "\\fR"
        if (d != "") line(d)
        next
    }
    /^   +[^ ]/ { sub(/^ +/, ""); line($0); next }
    { line($0) }
    '
}

# EXAMPLES of the "Examples:" block of a help text on stdin
examples_of() {
    awk '
    function esc(s) { gsub(/\\/, "\\e", s); gsub(/-/, "\\-", s); if (s ~ /^[.\047]/) s = "\\&" s; return s }
    /^Examples:$/ { on = 1; print ".SH EXAMPLES"; next }
    !on { next }
    /^  # / { if (nf) { print ".RE"; print ".fi"; nf = 0 } if (!text) print ".PP"; text = 1
              print esc(substr($0, 5)); next }
    /^  / { if (!nf) { print ".nf"; print ".RS 4"; nf = 1 } text = 0; print esc(substr($0, 3)); next }
    END { if (nf) { print ".RE"; print ".fi" } }
    '
}

usage_of() { # the Usage block of a help text on stdin
    awk '/^Usage:/ && !seen { on = 1; seen = 1; sub(/^Usage: /, "") } on && /^$/ { on = 0 } on { sub(/^       /, ""); print }' |
        sed 's/\\/\\e/g; s/-/\\-/g'
}

# ------------------------------------------------------------ shapematch(1)
{
    main=$("$BIN/shapematch" --help)
    cmds=$(printf '%s\n' "$main" | awk '/^Commands:/ { on = 1; next } on && /^$/ { on = 0 } on { print $1 }' |
        grep -v '^help$')
    echo ".TH SHAPEMATCH 1 \"$DATE\" \"shapematch $VERSION\" \"User Commands\""
    echo ".SH NAME"
    echo "shapematch \\- elastic shape matching: run jobs locally or on shapematchd"
    echo ".SH SYNOPSIS"
    echo ".nf"
    for c in $cmds; do "$BIN/shapematch" "$c" --help | usage_of; done
    echo ".fi"
    echo ".SH DESCRIPTION"
    printf '%s\n' "$main" | to_roff
    echo ".SH COMMANDS"
    for c in $cmds; do
        echo ".SS \"shapematch $c\""
        echo ".nf"
        "$BIN/shapematch" "$c" --help | usage_of
        echo ".fi"
        # the command's subsections become tagged headings under it
        "$BIN/shapematch" "$c" --help | to_roff | sed 's/^\.SS "\(.*\)"$/.PP\n.B "\1"/'
    done
    printf '%s\n' "$main" | examples_of
    echo ".SH SEE ALSO"
    echo ".BR shapematchd (8);"
    echo "the documentation in docs/ of the source tree (docs/user-guide.md, docs/python.md, docs/c-api.md)."
} >"$OUT/shapematch.1.tmp"
mv "$OUT/shapematch.1.tmp" "$OUT/shapematch.1"

# ----------------------------------------------------------- shapematchd(8)
{
    help=$("$BIN/shapematchd" --help)
    echo ".TH SHAPEMATCHD 8 \"$DATE\" \"shapematch $VERSION\" \"System Administration\""
    echo ".SH NAME"
    echo "shapematchd \\- the shapematch HTTP job daemon"
    echo ".SH SYNOPSIS"
    echo ".nf"
    printf '%s\n' "$help" | usage_of
    echo ".fi"
    echo ".SH DESCRIPTION"
    printf '%s\n' "$help" | to_roff
    printf '%s\n' "$help" | examples_of
    echo ".SH SEE ALSO"
    echo ".BR shapematch (1),"
    echo ".BR systemd.exec (5);"
    echo "server/README.md and deploy/README.md of the source tree."
} >"$OUT/shapematchd.8.tmp"
mv "$OUT/shapematchd.8.tmp" "$OUT/shapematchd.8"
