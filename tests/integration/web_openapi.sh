#!/usr/bin/env bash
# run.sh: weight 1 seconds 15
# The served OpenAPI document with a real validator (issue 11): a daemon
# serves /v1/openapi.yaml and, next to it, the two JSON schemas it refers
# to; web_openapi.mjs (npm @apidevtools/swagger-parser and ajv, installed
# by `make test` with npm ci from package-lock.json) validates the
# document fetched from the daemon, resolving every $ref over HTTP, and
# checks /v1/processes/match, /v1/conformance and /v1 against the
# document's own schemas.  Also: the schemas served are proto's files.
source "$(dirname "$0")/lib.sh"

if [ ! -d "$ROOT/node_modules/@apidevtools/swagger-parser" ]; then
    not_ok "the npm packages are installed (make test runs npm ci)" "no $ROOT/node_modules"
    echo "1..$n"
    exit 1
fi
start_daemon openapi --workers 1 || { not_ok "the daemon starts"; exit 1; }
ok "the daemon starts"
for f in params.schema.json events.schema.json; do
    code=$(curl -sS -o "$WORK/$f" -D "$WORK/h" -w '%{http_code}' "$BASE/v1/$f")
    if [ "$code" = 200 ] && cmp -s "$WORK/$f" "$ROOT/proto/$f" &&
        tr -d '\r' <"$WORK/h" | grep -qi '^content-type: application/schema+json'; then
        ok "/v1/$f is proto/$f (application/schema+json), beside the document that refers to it"
    else
        not_ok "/v1/$f" "code $code" "$(cat "$WORK/h")"
    fi
done
node_checks "the validator runs" "$ROOT/tests/integration/web_openapi.mjs" "$BASE"
check "no sanitizer reports" reports_clean
echo "1..$n"
