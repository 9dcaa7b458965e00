#!/usr/bin/env python3
"""Bounded floods of tests/integration/daemon_floods.sh (issue 28).

flood.py park PORT N BYTES SECONDS PROBE OUT
    N connections POST an OGC execute request declaring 3 x BYTES, send
    BYTES of it, then stall, in two waves: first as many as the daemon's
    --max-body-memory holds, at once, until /metrics shows it full; then
    the complete execute request in the file PROBE is sent (its status
    and body written to OUT); then the other connections at once.  Prints
    "sent CODE" (CODE: the probe's status) once every body is out, then
    watches SECONDS for the server to close them and prints one JSON
    object: opened, closed_by_server, longest_life.

Why two waves: bodies grow by doubling and a body that cannot grow is
dropped, so when more bodies than the budget holds grow at the same time
the ones that lose depend on how their growths interleave, and the budget
can end with room no body is left to take (a probe then read, not 503).
Bodies that fit grow without losing; later ones find it full.

Every socket is from 127.0.0.1 to 127.0.0.1:PORT and is closed at exit."""
import http.client, json, selectors, socket, sys, time

from daemon_metrics import gauge


def body_buffer(nbytes):
    """The daemon's buffer for nbytes (server/base/smd_body.c: 64 KiB,
    doubled until it holds them and a NUL)."""
    cap = 65536
    while cap < nbytes + 1:
        cap *= 2
    return cap


def wait_held(port, want, deadline=60.0):
    t0 = time.monotonic()
    while gauge(port, "shapematch_request_body_bytes") < want:
        if time.monotonic() - t0 > deadline:
            raise SystemExit("the daemon did not hold %d bytes of bodies within %g s" % (want, deadline))
        time.sleep(0.01)


def probe(port, path, out):
    with open(path, "rb") as f:
        body = f.read()
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
    try:
        c.request("POST", "/v1/processes/match/execution", body, {"Content-Type": "application/json"})
        r = c.getresponse()
        code, text = r.status, r.read()
    finally:
        c.close()
    with open(out, "wb") as f:
        f.write(text)
    return code


def park(port, n, nbytes, seconds, probe_path, probe_out):
    sel = selectors.DefaultSelector()
    socks = {}
    head = ("POST /v1/processes/match/execution HTTP/1.1\r\nHost: 127.0.0.1\r\n"
            "Content-Type: application/json\r\nContent-Length: %d\r\n\r\n" % (3 * nbytes)).encode()
    body = b'{"inputs": {"template": {"value": "' + b"A" * (nbytes - 36)

    def send(count):
        for _ in range(count):
            s = socket.create_connection(("127.0.0.1", port), timeout=10)
            try:
                s.sendall(head + body)
            except OSError:  # refused and closed while sending: its life ends now
                pass
            s.setblocking(False)
            socks[s] = time.monotonic()
            sel.register(s, selectors.EVENT_READ)

    cap = body_buffer(nbytes)
    fit = min(n, gauge(port, "shapematch_request_body_limit_bytes") // cap)
    send(fit)
    wait_held(port, fit * cap)
    code = probe(port, probe_path, probe_out)
    send(n - fit)
    print("sent", code, flush=True)
    stats = {"opened": n, "closed_by_server": 0, "longest_life": 0.0}
    end = time.monotonic() + seconds
    while socks and time.monotonic() < end:
        for key, _ in sel.select(timeout=0.1):
            s = key.fileobj
            try:
                data = s.recv(65536)
            except OSError:
                data = b""
            if not data:
                life = time.monotonic() - socks.pop(s)
                stats["closed_by_server"] += 1
                stats["longest_life"] = round(max(stats["longest_life"], life), 2)
                sel.unregister(s)
                s.close()
    for s in socks:
        s.close()
    print(json.dumps(stats))


if __name__ == "__main__":
    if sys.argv[1] == "park" and len(sys.argv) == 8:
        park(int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), float(sys.argv[5]),
             sys.argv[6], sys.argv[7])
    else:
        sys.exit("usage: flood.py park PORT N BYTES SECONDS PROBE OUT")
