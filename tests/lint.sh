#!/usr/bin/env bash
# make lint: where the house is crowded.  Prints the longest source files
# of core/ proto/ server/ client/ and the longest and most complex
# functions (Debian's pmccabe: traditional McCabe cyclomatic complexity,
# lines from the function's first to its last line), the top N of each,
# with the entries beyond the house's size guide marked "<- over guide".
# The guide is the numbers below: files of ~900 lines at most, functions
# of ~120 lines at most and of cyclomatic complexity ~30 at most.
# Informative, not a gate: always exits 0.
#
#   tests/lint.sh            top 15 of each
#   LINT_TOP=30 tests/lint.sh
set -u
cd "$(dirname "$0")/.."

top=${LINT_TOP:-15}
file_guide=900 # lines per file
func_guide=120 # lines per function
ccn_guide=30   # cyclomatic complexity per function
dirs=(core proto server client)

mapfile -t files < <(find "${dirs[@]}" -name '*.[ch]' -type f 2>/dev/null | sort)
if [ "${#files[@]}" -eq 0 ]; then
    echo "lint: no source files under ${dirs[*]}"
    exit 0
fi

mark() { # value guide
    if [ "$1" -gt "$2" ]; then printf '  <- over guide'; fi
}

echo "Longest files (lines; guide ~$file_guide):"
wc -l "${files[@]}" | grep -v ' total$' | sort -k1,1nr -k2 | head -n "$top" |
    while read -r n f; do
        printf '  %6d  %s%s\n' "$n" "$f" "$(mark "$n" "$file_guide")"
    done
over=$(wc -l "${files[@]}" | grep -v ' total$' | awk -v g=$file_guide '$1 > g' | wc -l)
echo "  ($over of ${#files[@]} files over the guide)"

if ! command -v pmccabe >/dev/null 2>&1; then
    echo
    echo "lint: pmccabe is not installed (Debian package pmccabe: make deps installs it);"
    echo "      the function figures are left out."
    exit 0
fi

# pmccabe columns: modified CCN, traditional CCN, statements, first line,
# lines, "file(line): function".  Only .c files: functions live there
# (and pmccabe counts the static inline helpers of the .h files too,
# which would appear twice).
mapfile -t cfiles < <(printf '%s\n' "${files[@]}" | grep '\.c$')
funcs=$(pmccabe "${cfiles[@]}" 2>/dev/null |
    awk -F'\t' '{ split($6, a, ": "); sub(/\(/, ":", a[1]); sub(/\)$/, "", a[1]); print $2 "\t" $5 "\t" a[1] "\t" a[2] }')
nfuncs=$(printf '%s\n' "$funcs" | grep -c .)

echo
echo "Longest functions (lines; guide ~$func_guide):"
printf '%s\n' "$funcs" | sort -t$'\t' -k2,2nr -k3 | head -n "$top" |
    while IFS=$'\t' read -r ccn len where name; do
        printf '  %6d  %-40s %s%s\n' "$len" "$where" "$name" "$(mark "$len" "$func_guide")"
    done
over=$(printf '%s\n' "$funcs" | awk -F'\t' -v g=$func_guide '$2 > g' | wc -l)
echo "  ($over of $nfuncs functions over the guide)"

echo
echo "Most complex functions (cyclomatic complexity; guide ~$ccn_guide):"
printf '%s\n' "$funcs" | sort -t$'\t' -k1,1nr -k3 | head -n "$top" |
    while IFS=$'\t' read -r ccn len where name; do
        printf '  %6d  %-40s %s%s\n' "$ccn" "$where" "$name" "$(mark "$ccn" "$ccn_guide")"
    done
over=$(printf '%s\n' "$funcs" | awk -F'\t' -v g=$ccn_guide '$1 > g' | wc -l)
echo "  ($over of $nfuncs functions over the guide)"
exit 0
