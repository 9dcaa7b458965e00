#!/usr/bin/env python3
"""Bounded floods of tests/integration/daemon_floods.sh (issue 28).

flood.py park PORT N BYTES SECONDS
    N connections POST an OGC execute request declaring 3 x BYTES, send
    BYTES of it at once, then stall.  Prints "sent" (flushed) once every
    body is out, then watches SECONDS for the server to close them and
    prints one JSON object: opened, closed_by_server, longest_life.

Every socket is from 127.0.0.1 to 127.0.0.1:PORT and is closed at exit."""
import json, selectors, socket, sys, time


def park(port, n, nbytes, seconds):
    sel = selectors.DefaultSelector()
    socks = {}
    head = ("POST /v1/processes/match/execution HTTP/1.1\r\nHost: 127.0.0.1\r\n"
            "Content-Type: application/json\r\nContent-Length: %d\r\n\r\n" % (3 * nbytes)).encode()
    body = b'{"inputs": {"template": {"value": "' + b"A" * (nbytes - 36)
    for _ in range(n):
        s = socket.create_connection(("127.0.0.1", port), timeout=10)
        s.sendall(head + body)
        s.setblocking(False)
        socks[s] = time.monotonic()
        sel.register(s, selectors.EVENT_READ)
    print("sent", flush=True)
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
    if sys.argv[1] == "park":
        park(int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), float(sys.argv[5]))
    else:
        sys.exit("usage: flood.py park PORT N BYTES SECONDS")
