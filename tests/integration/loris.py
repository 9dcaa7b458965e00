#!/usr/bin/env python3
"""Slow-loris driver of tests/integration/daemon_slowloris.sh (issue 8).

loris.py PORT SECONDS ADDRS PER_ADDR STATUS_PATH [MODE]
Opens PER_ADDR sockets from each source address in ADDRS (comma list,
127.0.0.2... all reach loopback on Linux) to 127.0.0.1:PORT; MODE headers
(default) sends a request line then one header byte per second on each;
MODE body sends complete upload headers (Content-Length 10 MB) then one
body byte per second; MODE bulk sends them with 200 KB of body at once, then
one byte per second (a rate that stays above --min-upload-rate for minutes);
MODE stream opens the NDJSON event stream of STATUS_PATH's job and reads it.  A socket the server closes is reopened on the next
tick, as a real attacker would.  Meanwhile, every second, /healthz and
STATUS_PATH are fetched from 127.0.0.1 (a fresh connection each, 2 s
timeout, or LORIS_PROBE_SECONDS).  Prints one JSON object: probes, answered, max and median probe
latency, sockets opened, closed by the server, and the longest life of a
socket the server closed."""
import json, os, selectors, socket, sys, time

port, seconds = int(sys.argv[1]), float(sys.argv[2])
addrs, per = sys.argv[3].split(","), int(sys.argv[4])
status_path = sys.argv[5]
mode = sys.argv[6] if len(sys.argv) > 6 else "headers"
# a probe's time limit (LORIS_PROBE_SECONDS, default 2)
probe_limit = float(os.environ.get("LORIS_PROBE_SECONDS", "2"))
sel = selectors.DefaultSelector()
socks = {}  # sock -> (addr, opened at)
stats = {"opened": 0, "closed_by_server": 0, "connect_failed": 0, "longest_life": 0.0}


def start(addr):
    s = socket.socket()
    s.setblocking(False)
    try:
        s.bind((addr, 0))
        s.connect_ex(("127.0.0.1", port))
    except OSError:
        s.close()
        stats["connect_failed"] += 1
        return
    socks[s] = (addr, time.monotonic(), [False])
    sel.register(s, selectors.EVENT_READ)
    stats["opened"] += 1


def first_bytes():
    if mode == "stream":
        return (b"GET " + status_path.encode() + b"/events HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                b"Accept: application/x-ndjson\r\n\r\n")
    if mode == "bulk":
        return (b"POST /v1/jobs HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 10000000\r\n"
                b"Content-Type: multipart/form-data; boundary=b\r\n\r\n--b\r\nContent-Disposition:"
                b" form-data; name=\"template\"; filename=\"t.mesh\"\r\n\r\n" + b"x" * 200000)
    if mode == "body":
        return (b"POST /v1/jobs HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 10000000\r\n"
                b"Content-Type: multipart/form-data; boundary=b\r\n\r\n--b\r\n")
    return b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n"


def drop(s, by_server):
    addr, t0, _ = socks.pop(s)
    sel.unregister(s)
    s.close()
    if by_server:
        stats["closed_by_server"] += 1
        stats["longest_life"] = max(stats["longest_life"], time.monotonic() - t0)


def tick():
    for s, (addr, t0, sent) in list(socks.items()):
        try:
            if not sent[0]:
                sent.append(first_bytes())  # what is left of it: sent[1]
                sent[0] = True
            if len(sent) > 1 and sent[1]:
                sent[1] = sent[1][s.send(sent[1]):]
            elif mode != "stream":
                s.send(b"x")
        except BlockingIOError:
            pass
        except OSError:
            drop(s, sent[0])
    live = {}
    for addr, _, _ in socks.values():
        live[addr] = live.get(addr, 0) + 1
    for addr in addrs:
        for _ in range(per - live.get(addr, 0)):
            start(addr)


def probe(path):
    t0 = time.monotonic()
    try:
        c = socket.create_connection(("127.0.0.1", port), timeout=probe_limit)
        c.settimeout(max(0.01, probe_limit - (time.monotonic() - t0)))
        c.sendall(b"GET " + path.encode() + b" HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n")
        data = b""
        while b"\r\n\r\n" not in data:
            chunk = c.recv(4096)
            if not chunk:
                break
            data += chunk
        c.close()
        ok = data.startswith(b"HTTP/1.1 200")
    except OSError:
        ok = False
    dt = time.monotonic() - t0
    return ok and dt <= probe_limit, dt


def poll_reads(until):
    while True:
        left = until - time.monotonic()
        if left <= 0:
            return
        for key, _ in sel.select(timeout=left):
            s = key.fileobj
            try:
                if not s.recv(65536):
                    drop(s, True)
            except BlockingIOError:
                pass
            except OSError:
                drop(s, True)


end = time.monotonic() + seconds
lat, answered, probes = [], 0, 0
tick()
poll_reads(time.monotonic() + 1.0)
while time.monotonic() < end:
    t_tick = time.monotonic()
    tick()
    for path in ("/healthz", status_path):
        ok, dt = probe(path)
        probes += 1
        answered += ok
        lat.append(dt)
    poll_reads(t_tick + 1.0)
peak = len(socks)
for s in list(socks):
    drop(s, False)
lat.sort()
print(json.dumps({"probes": probes, "answered": answered,
                  "max_latency": round(lat[-1], 3) if lat else None,
                  "median_latency": round(lat[len(lat) // 2], 3) if lat else None,
                  "sockets_at_end": peak, **{k: (round(v, 2) if isinstance(v, float) else v)
                                             for k, v in stats.items()}}))
