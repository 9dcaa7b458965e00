"""Reading the daemon's /metrics from the flood drivers (flood.py,
warp_flood.py): one gauge's value, so that a driver waits for a state the
daemon reports instead of for time."""
import http.client


def gauge(port, name):
    """The value of the row NAME (no labels) of GET /metrics on 127.0.0.1:PORT."""
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
    try:
        c.request("GET", "/metrics")
        text = c.getresponse().read().decode()
    finally:
        c.close()
    for line in text.splitlines():
        if line.startswith(name + " "):
            return int(float(line.split()[1]))
    raise SystemExit("no %s in /metrics" % name)
