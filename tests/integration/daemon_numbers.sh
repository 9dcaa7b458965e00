#!/usr/bin/env bash
# Every number a client sends is bounded before it is converted or
# anything is allocated from it, and a value outside answers 400/422
# problem+json naming it (issue 28).  The rows come from the tables
# themselves, so that a new parameter is walked too:
# - the integer query and header parameters of proto/openapi.yaml
#   (limit, offset, after, Last-Event-ID), each with its maximum + 1
#   (2^53 when it has none: the largest the daemon takes is 2^53 - 1),
#   2^64, 40 digits, -1, 1e3 and 0x10;
# - the numeric members of proto/params.schema.json (the job parameter
#   table, test_proto_params checks them against core/sm_params.c), each
#   just past each bound, 1e300 past a maximum, -1e300 past a minimum, an
#   integer member also 2^63;
# - the multipart parts: a part name outside the known ones.
# The daemon's own flags are walked from its table by
# tests/unit/test_server_config.c.
source "$(dirname "$0")/lib.sh"

# the parameters are checked before the meshes are read: a small mesh
# and a stand-in solution do (a value let through fails on them, with a
# detail that does not name the parameter)
MESH=$ROOT/examples/2d/template.mesh
printf 'MeshVersionFormatted 2\n' >"$WORK/stand-in.sol"
start_daemon bounds --workers 1 || { not_ok "the daemon starts"; exit 1; }

# problem CODE_FILE BODY_FILE NAME: 400/422, problem+json, detail names NAME
problem() {
    local code
    code=$(cat "$1")
    [[ "$code" == 400 || "$code" == 422 ]] &&
        jq -e --arg n "$3" '(.detail | ascii_downcase | contains($n | ascii_downcase)) and .status >= 400' "$2" >/dev/null
}

# ----------------------------------------- query and header parameters
python3 - "$(dirname "$0")/../../proto/openapi.yaml" >"$WORK/qrows.txt" <<'PY'
import re, sys, yaml
d = yaml.safe_load(open(sys.argv[1]))
comp = d.get("components", {}).get("parameters", {})
for path, ops in d["paths"].items():
    common = ops.get("parameters", [])
    for method, op in ops.items():
        if method != "get" or not isinstance(op, dict):
            continue
        for p in common + op.get("parameters", []):
            if "$ref" in p:
                p = comp[p["$ref"].split("/")[-1]]
            s = p.get("schema", {})
            if s.get("type") == "integer" and p["in"] in ("query", "header"):
                # any id (jobID, batchID): one that names nothing, the
                # values are checked before the lookup
                print(re.sub(r"\{[A-Za-z]*ID\}", "0" * 32, path), p["in"], p["name"],
                      s.get("maximum", 2**53 - 1) + 1)
PY
rows=0 bad=""
while read -r path where name over; do
    rows=$((rows + 1))
    for v in "$over" 18446744073709551616 1234567890123456789012345678901234567890 -1 1e3 0x10; do
        if [ "$where" = header ]; then
            hcurl -o "$WORK/q.json" -w '%{http_code}' -H "$name: $v" "$BASE$path" >"$WORK/q.code"
        else
            hcurl -o "$WORK/q.json" -w '%{http_code}' "$BASE$path?$name=$v" >"$WORK/q.code"
        fi
        problem "$WORK/q.code" "$WORK/q.json" "$name" || bad="$bad $name=$v($(cat "$WORK/q.code"))"
    done
done <"$WORK/qrows.txt"
check "the $rows integer query and header parameters of the OpenAPI document refuse 6 values past their bounds each with 400 problem+json naming them${bad:+ (bad:$bad)}" \
    test "$rows" -ge 4 -a -z "$bad"

# ------------------------------------------------------ job parameters
python3 - "$(dirname "$0")/../../proto/params.schema.json" >"$WORK/prows.txt" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
for name, s in d["properties"].items():
    t = s.get("type")
    if t not in ("integer", "number"):
        continue
    vals = []
    step = 1 if t == "integer" else 0
    if "maximum" in s or "exclusiveMaximum" in s:
        vals += ["1e300"]
    if "minimum" in s or "exclusiveMinimum" in s:
        vals += ["-1e300"]
    if "maximum" in s:
        vals.append(repr(s["maximum"] + 1))
    if "exclusiveMaximum" in s:
        vals.append(repr(s["exclusiveMaximum"] + step))
    if "minimum" in s:
        vals.append(repr(s["minimum"] - 1))
    if "exclusiveMinimum" in s:
        vals.append(repr(s["exclusiveMinimum"] - step))
    if t == "integer":  # past what a JSON reader holds as an integer
        vals.append("9223372036854775808")
    print(name, " ".join(vals))
PY
rows=0 tried=0 bad=""
while read -r name vals; do
    rows=$((rows + 1))
    for v in $vals; do
        tried=$((tried + 1))
        hcurl -o "$WORK/p.json" -w '%{http_code}' \
            -F "params={\"clamp\": {\"kind\": \"none\"}, \"$name\": $v}" -F "template=@$MESH" \
            -F "target_mesh=@$MESH" -F "target_sol=@$WORK/stand-in.sol" "$BASE/v1/jobs" >"$WORK/p.code"
        # the JSON reader refuses an integer past 2^63 before any member
        # is read: its detail quotes the value instead of the name
        problem "$WORK/p.code" "$WORK/p.json" "$name" || problem "$WORK/p.code" "$WORK/p.json" "'$v'" ||
            bad="$bad $name=$v($(cat "$WORK/p.code"): $(jq -r .detail "$WORK/p.json" | head -c 120))"
    done
done <"$WORK/prows.txt"
check "the $rows numeric job parameters refuse $tried values past their bounds with 400/422 problem+json naming them${bad:+ (bad:$bad)}" \
    test "$rows" -ge 10 -a -z "$bad"

# ------------------------------------------------------------- parts
hcurl -o "$WORK/m.json" -w '%{http_code}' -F "frobnicate=1" -F "template=@$MESH" \
    "$BASE/v1/jobs" >"$WORK/m.code"
check "a part outside the known ones: 400 problem+json naming it ($(cat "$WORK/m.code"))" \
    problem "$WORK/m.code" "$WORK/m.json" frobnicate
n_jobs=$(hcurl "$BASE/v1/jobs" | jq '.jobs | length')
check "none of them made a job ($n_jobs)" test "$n_jobs" = 0
stop_daemon
check "no sanitizer report in the daemon log" reports_clean
echo "1..$n"
