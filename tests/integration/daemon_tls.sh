#!/usr/bin/env bash
# TLS (issue 8): --tls-cert/--tls-key with a self-signed certificate made
# at test time (openssl); curl --cacert completes the handshake over TLS
# 1.2 and 1.3, TLS 1.1 and a wrong CA are refused, plain HTTP gets no
# answer; the client takes --cacert; SIGHUP reloads the certificate (a
# new one is served to the next connection, logged tls_reloaded).
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
ok "gmsh builds the test meshes"
# mkcert NAME CN: a self-signed certificate for 127.0.0.1
mkcert() {
    openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -days 2 -subj "/CN=$2" \
        -addext "subjectAltName=IP:127.0.0.1" -keyout "$WORK/$1.key" -out "$WORK/$1.pem" \
        >"$WORK/openssl.log" 2>&1
}
if mkcert one shapematch-one && mkcert two shapematch-two && mkcert other other-ca; then
    ok "self-signed certificates made with openssl"
else
    not_ok "openssl makes certificates" "$(cat "$WORK/openssl.log")"
    exit 1
fi
cp "$WORK/one.pem" "$WORK/cert.pem"
cp "$WORK/one.key" "$WORK/cert.key"
start_daemon tls --workers 1 --tls-cert "$WORK/cert.pem" --tls-key "$WORK/cert.key" ||
    { not_ok "the daemon starts with TLS"; exit 1; }
ok "the daemon starts with --tls-cert and --tls-key"
S=https://${BASE#http://}
tcode() { curl -sS --max-time $((10 * SLOW)) -o "$WORK/t.out" -w '%{http_code}' "$@" 2>"$WORK/t.err"; }
if [ "$(tcode --cacert "$WORK/one.pem" "$S/healthz")" = 200 ]; then
    ok "curl --cacert: the handshake completes, /healthz 200"
else
    not_ok "curl --cacert: /healthz" "$(cat "$WORK/t.err")"
fi
for v in 1.2 1.3; do
    if [ "$(tcode --cacert "$WORK/one.pem" --tlsv$v --tls-max $v "$S/healthz")" = 200 ]; then
        ok "TLS $v is accepted"
    else
        not_ok "TLS $v is accepted" "$(cat "$WORK/t.err")"
    fi
done
c=$(tcode --cacert "$WORK/one.pem" --tlsv1.1 --tls-max 1.1 "$S/healthz")
if [ "$c" = 000 ]; then
    ok "TLS 1.1 is refused"
else
    not_ok "TLS 1.1 is refused" "code $c"
fi
c=$(tcode --cacert "$WORK/other.pem" "$S/healthz")
if [ "$c" = 000 ] && grep -qi "certificate" "$WORK/t.err"; then
    ok "a wrong CA is refused by the client: $(head -c 120 "$WORK/t.err")"
else
    not_ok "a wrong CA is refused" "code $c" "$(cat "$WORK/t.err")"
fi
c=$(tcode "$BASE/healthz")
if [ "$c" != 200 ]; then
    ok "plain HTTP on the TLS port gets no answer (code $c)"
else
    not_ok "plain HTTP on the TLS port is refused"
fi
id=$("$BIN/shapematch" submit --server "$S" --cacert "$WORK/one.pem" --template "$DISK" --target-mesh "$BOX" \
    --target-sol "$BOXSOL" --clamp-ball 0,0,0.1 --max-iter 5 2>"$WORK/client.err" | tail -1)
if [ -n "$id" ] && "$BIN/shapematch" status --server "$S" --cacert "$WORK/one.pem" "$id" >/dev/null 2>&1; then
    ok "the client with --cacert submits and reads the status over TLS"
else
    not_ok "the client with --cacert" "$id" "$(cat "$WORK/client.err")"
fi
if ! "$BIN/shapematch" status --server "$S" --cacert "$WORK/other.pem" "${id:-0}" >/dev/null 2>"$WORK/client.err"; then
    ok "the client with a wrong --cacert fails: $(head -1 "$WORK/client.err")"
else
    not_ok "the client with a wrong --cacert fails"
fi

# SIGHUP: certificate two replaces one
cp "$WORK/two.pem" "$WORK/cert.pem"
cp "$WORK/two.key" "$WORK/cert.key"
kill -HUP "$DPID"
reloaded() { grep -q '"event":"tls_reloaded"' "$DLOG"; }
if poll 10 reloaded && [ "$(tcode --cacert "$WORK/two.pem" "$S/healthz")" = 200 ] &&
    [ "$(tcode --cacert "$WORK/one.pem" "$S/healthz")" = 000 ]; then
    ok "SIGHUP reloads the certificate: the new one is served, the old CA no longer matches"
else
    not_ok "SIGHUP reloads the certificate" "$(grep reload "$DLOG" | tail -2)"
fi
if stop_daemon && reports_clean; then
    ok "SIGTERM stops the daemon, no sanitizer report"
else
    not_ok "clean stop"
fi
echo "1..$n"
