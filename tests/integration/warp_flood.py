#!/usr/bin/env python3
"""Bounded warp floods of tests/integration/daemon_warp_bounds.sh (issues 36
and 37).  Every socket is from 127.0.0.1 to 127.0.0.1:PORT.

warp_flood.py flood PORT JOB DIR N CLIENTS
    N POST /v1/jobs/JOB/warp requests, CLIENTS at a time, their bodies the
    files DIR/*.body cycled (the Content-Type in DIR/NAME.type), while
    GET /healthz is asked every 50 ms.  Prints one JSON object: codes
    (status -> count), warps (seconds of all), healthz_n, healthz_max
    (the slowest answer, s), healthz_failed.

warp_flood.py park PORT JOB N BYTES
    N connections POST a CSV warp body declaring 2 x BYTES, send BYTES
    of it and stall, one after another (each once the daemon has read it).  Prints "sent" (flushed) once every body is out ("sent,
    K refused" when K connections were closed on it), then waits for a
    line on stdin and closes them."""
import glob, http.client, json, os, socket, sys, threading, time

from daemon_metrics import gauge


def flood(port, job, folder, n, clients):
    bodies = []
    for path in sorted(glob.glob(os.path.join(folder, "*.body"))):
        with open(path, "rb") as f, open(path[:-5] + ".type") as t:
            bodies.append((f.read(), t.read().strip()))
    codes, lock, done = {}, threading.Lock(), threading.Event()
    todo = list(range(n))

    def client():
        while True:
            with lock:
                if not todo:
                    return
                i = todo.pop()
            body, ctype = bodies[i % len(bodies)]
            c = http.client.HTTPConnection("127.0.0.1", port, timeout=120)
            try:
                c.request("POST", "/v1/jobs/%s/warp" % job, body, {"Content-Type": ctype})
                code = str(c.getresponse().status)
            except (OSError, http.client.HTTPException) as e:
                code = type(e).__name__
            finally:
                c.close()
            with lock:
                codes[code] = codes.get(code, 0) + 1

    probes = {"n": 0, "max": 0.0, "failed": 0}

    def probe():
        while not done.is_set():
            t0 = time.monotonic()
            try:
                c = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
                c.request("GET", "/healthz")
                ok = c.getresponse().status == 200
                c.close()
            except (OSError, http.client.HTTPException):
                ok = False
            dt = time.monotonic() - t0
            probes["n"] += 1
            probes["max"] = max(probes["max"], dt)
            probes["failed"] += 0 if ok else 1
            time.sleep(0.05)

    t0 = time.monotonic()
    p = threading.Thread(target=probe)
    p.start()
    workers = [threading.Thread(target=client) for _ in range(clients)]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    done.set()
    p.join()
    print(json.dumps({"codes": codes, "warps": round(time.monotonic() - t0, 2),
                      "healthz_n": probes["n"], "healthz_max": round(probes["max"], 3),
                      "healthz_failed": probes["failed"]}))


def queued(port, peer):
    """Bytes still on the way from the client port peer to the daemon's port:
    the client's unsent queue plus the daemon's unread one (/proc/net/tcp*)."""
    total, seen = 0, False
    for name in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            with open(name) as f:
                rows = f.readlines()[1:]
        except OSError:
            continue
        for row in rows:
            cols = row.split()
            local, remote = int(cols[1].rsplit(":", 1)[1], 16), int(cols[2].rsplit(":", 1)[1], 16)
            tx, rx = (int(v, 16) for v in cols[4].split(":"))
            if (local, remote) == (peer, port):
                total, seen = total + tx, True
            elif (local, remote) == (port, peer):
                total, seen = total + rx, True
    return total if seen else None


def held(port):
    """Request bodies the daemon holds now, in bytes."""
    return gauge(port, "shapematch_request_body_bytes")


def settle(port, sock, deadline=60.0):
    """Waits until the daemon has read every byte sent on sock and its count
    of held bodies stands still: bodies parked one at a time fill the budget
    in a known order (at the same time, which of them keep their memory
    depends on how their growths interleave)."""
    peer, t0, last = sock.getsockname()[1], time.monotonic(), None
    while time.monotonic() - t0 < deadline:
        if not queued(port, peer):
            now = held(port)
            if now == last:
                return
            last = now
        time.sleep(0.02)
    raise SystemExit("the daemon did not read a parked body within %g s" % deadline)


def park(port, job, n, nbytes):
    head = ("POST /v1/jobs/%s/warp HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: text/csv\r\n"
            "Content-Length: %d\r\n\r\n" % (job, 2 * nbytes)).encode()
    line = b"0.125,0.25\n"
    body = b"x,y\n" + line * ((nbytes - 4) // len(line))
    socks, refused = [], 0
    for _ in range(n):
        try:
            s = socket.create_connection(("127.0.0.1", port), timeout=60)
            socks.append(s)
            s.sendall(head + body)
            settle(port, s)
        except OSError:  # answered and closed early: counted, not kept
            refused += 1
    print("sent" if not refused else "sent, %d refused" % refused, flush=True)
    sys.stdin.readline()
    for s in socks:
        s.close()


if __name__ == "__main__":
    if sys.argv[1] == "flood":
        flood(int(sys.argv[2]), sys.argv[3], sys.argv[4], int(sys.argv[5]), int(sys.argv[6]))
    elif sys.argv[1] == "park":
        park(int(sys.argv[2]), sys.argv[3], int(sys.argv[4]), int(sys.argv[5]))
    else:
        sys.exit("usage: warp_flood.py flood PORT JOB DIR N CLIENTS | park PORT JOB N BYTES")
