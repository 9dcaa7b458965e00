"""shapematch.Client: a shapematchd client on the standard library alone
(urllib, and the Server-Sent Events parsed here), with the keywords of
shapematch.match.

    c = shapematch.Client("http://127.0.0.1:8080", token="...")
    job = c.submit("template.mesh", target_mesh="bg.mesh", target_sol="bg.sol",
                   clamp_ball=(0.5, 0.5, 0.04), max_iter=200)
    for event in job.events(): ...
    result = job.wait(progress=lambda it, J, err: print(it, err))
    job.results("out")

Requests answered 503 or 429 are retried after the Retry-After the daemon
sends (seconds or an HTTP date), up to `retries` times.
"""
import email.utils
import json
import os
import time
import urllib.error
import urllib.parse
import urllib.request
import uuid

FINAL = ("successful", "failed", "dismissed")
# run's default --format: the files results() writes by default
DEFAULT_FORMATS = "mesh,vtu,sol"
_FILES = {  # format -> (resource, query format, file name); proto/sm_proto_vocab.h
    "mesh": ("mesh", "mesh", "result.mesh"), "meshb": ("mesh", "meshb", "result.meshb"),
    "vtu": ("mesh", "vtu", "result.vtu"), "binary": ("mesh", "binary", "result.smmesh"),
    "sol": ("displacement", "sol", "displacement.sol"),
    "solb": ("displacement", "solb", "displacement.solb"),
}


class HTTPError(RuntimeError):
    """A request the daemon refused: status (the HTTP code), problem (its
    problem+json document as a dict, or None); str() is its detail."""

    def __init__(self, status, problem, text):
        super().__init__(text)
        self.status = status
        self.problem = problem


def _retry_after(value, now=None):
    """Seconds to wait for a Retry-After header (delta-seconds or an
    HTTP-date); 1 when absent or unreadable."""
    if value is None:
        return 1.0
    value = value.strip()
    if value.isdigit():
        return float(value)
    try:
        when = email.utils.parsedate_to_datetime(value).timestamp()
    except (TypeError, ValueError):
        return 1.0
    return max(0.0, when - (now if now is not None else time.time()))


def _multipart(parts):
    """(body, content type) of a multipart/form-data body; parts: (name,
    filename or None, bytes)."""
    boundary = "shapematch-" + uuid.uuid4().hex
    out = []
    for name, filename, data in parts:
        disp = 'form-data; name="%s"' % name
        if filename is not None:
            disp += '; filename="%s"' % filename.replace('"', "_")
        out.append(("--%s\r\nContent-Disposition: %s\r\n" % (boundary, disp)).encode())
        out.append(b"Content-Type: application/octet-stream\r\n\r\n" if filename is not None
                   else b"Content-Type: application/json\r\n\r\n")
        out.append(data)
        out.append(b"\r\n")
    out.append(("--%s--\r\n" % boundary).encode())
    return b"".join(out), "multipart/form-data; boundary=" + boundary


def sse_events(lines):
    """Server-Sent Events of an iterable of byte lines: (id or None, event
    type, data text) per event (W3C EventSource's rules: comments skipped,
    data lines joined by newlines, an event ends at a blank line)."""
    ev_id, ev_type, data = None, None, []
    for raw in lines:
        line = raw.decode("utf-8", "replace").rstrip("\r\n")
        if not line:
            if data:
                yield ev_id, ev_type or "message", "\n".join(data)
            ev_id, ev_type, data = None, None, []
            continue
        if line.startswith(":"):
            continue
        field, _, value = line.partition(":")
        if value.startswith(" "):
            value = value[1:]
        if field == "data":
            data.append(value)
        elif field == "event":
            ev_type = value
        elif field == "id":
            ev_id = value
    if data:
        yield ev_id, ev_type or "message", "\n".join(data)


class Client:
    """A shapematchd at url (http://host:port), with a bearer token or none."""

    def __init__(self, url, token=None, *, retries=5, timeout=60.0, max_retry_wait=300.0):
        self.url = url.rstrip("/")
        self.token = token
        self.retries = retries
        self.timeout = timeout
        self.max_retry_wait = max_retry_wait

    def _request(self, method, path, body=None, headers=None, stream=False):
        hdrs = dict(headers or {})
        if self.token:
            hdrs["Authorization"] = "Bearer " + self.token
        attempt = 0
        while True:
            req = urllib.request.Request(self.url + path, data=body, method=method, headers=hdrs)
            try:
                return urllib.request.urlopen(req, timeout=None if stream else self.timeout)
            except urllib.error.HTTPError as e:
                if e.code in (429, 503) and attempt < self.retries:
                    wait = min(_retry_after(e.headers.get("Retry-After")), self.max_retry_wait)
                    e.read()
                    e.close()
                    attempt += 1
                    time.sleep(wait)
                    continue
                text = e.read().decode("utf-8", "replace")
                problem = None
                try:
                    problem = json.loads(text)
                except ValueError:
                    pass
                detail = problem.get("detail") or problem.get("title") if isinstance(
                    problem, dict) else text
                raise HTTPError(e.code, problem, "%s %s: HTTP %d: %s" % (
                    method, path, e.code, detail)) from None

    def _json(self, method, path, **kw):
        with self._request(method, path, **kw) as r:
            return json.loads(r.read().decode())

    def submit(self, template, *, target_mesh=None, target_sol=None, target_surface=None,
               target_image=None, clamp_ball=None, clamp_elements=None, clamp_vertices=None, no_clamp=False,
               idempotency_key=None, name=None, **params):
        """Sends a job (files by path; the keywords of shapematch.match);
        returns its Job.  An idempotency_key makes a retried submission
        return the job the first one created; name (1 to 200 bytes of
        text) labels the job in the daemon's lists, status and the web
        app (Job.status()["name"])."""
        from . import _clamp, _json as params_json  # the params document as match builds it
        doc = dict(params)
        doc["clamp"] = _clamp(clamp_ball, clamp_elements, clamp_vertices, no_clamp, doc)
        parts = []
        for part, path in (("template", template), ("target_mesh", target_mesh),
                           ("target_sol", target_sol), ("target_surface", target_surface),
                           ("target_image", target_image)):
            if path is None:
                continue
            if not isinstance(path, (str, bytes, os.PathLike)):
                raise TypeError("%s: Client.submit takes paths" % part)
            with open(path, "rb") as f:
                parts.append((part, os.path.basename(os.fsdecode(path)), f.read()))
        parts.append(("params", None, params_json(doc).encode()))
        if name is not None:
            parts.append(("name", None, str(name).encode()))
        body, ctype = _multipart(parts)
        headers = {"Content-Type": ctype, "Accept": "application/json"}
        # a retried submission must not create a second job
        headers["Idempotency-Key"] = idempotency_key or uuid.uuid4().hex
        info = self._json("POST", "/v1/jobs", body=body, headers=headers)
        return Job(self, info["jobID"])

    def job(self, job_id):
        return Job(self, job_id)


class Job:
    """A job on the daemon."""

    def __init__(self, client, job_id):
        self.client = client
        self.id = job_id

    def __repr__(self):
        return "<shapematch.Job %s>" % self.id

    def status(self):
        """The status document (dict: status, progress, ...)."""
        return self.client._json("GET", "/v1/jobs/" + self.id)

    def cancel(self):
        """Cancels a queued or running job (deletes a finished one)."""
        return self.client._json("DELETE", "/v1/jobs/" + self.id)

    def events(self, after=0):
        """The job's events as dicts, replayed then followed live until the
        job is final (the closing "status" event is the last); resumes
        after a lost connection with Last-Event-ID."""
        last = after
        while True:
            headers = {"Accept": "text/event-stream"}
            if last:
                headers["Last-Event-ID"] = str(last)
            try:
                with self.client._request("GET", "/v1/jobs/%s/events" % self.id,
                                          headers=headers, stream=True) as r:
                    for ev_id, _type, data in sse_events(r):
                        event = json.loads(data)
                        if ev_id is not None:
                            last = int(ev_id)
                        yield event
                        if event.get("type") == "status":
                            return
            except (ConnectionError, urllib.error.URLError) as e:
                if isinstance(e, urllib.error.HTTPError):
                    raise
                time.sleep(0.5)  # the stream broke before the end: resume

    def wait(self, progress=None):
        """Follows the job to its end; returns a RemoteResult when it
        succeeded, raises shapematch.ShapematchError when it failed or was
        dismissed.  progress(iteration, J, boundary_l2) as in match:
        returning False cancels the job."""
        from . import ShapematchError
        final = None
        message = None
        cancelled = False
        for event in self.events():
            t = event.get("type")
            if t == "progress" and progress is not None and not cancelled:
                if progress(event.get("iteration"), event.get("J"),
                            event.get("boundary_l2")) is False:
                    # once: a second DELETE would delete the dismissed job
                    cancelled = True
                    self.cancel()
            elif t in ("failed", "cancelled"):
                message = event.get("message")
            elif t == "status":
                final = event.get("status")
        if final != "successful":
            raise ShapematchError("job %s %s%s" % (self.id, final or "ended",
                                                   ": " + message if message else ""),
                                  "failed" if final == "failed" else "cancelled")
        return RemoteResult(self)

    def _download(self, resource, fmt, dest):
        path = "/v1/jobs/%s/results/%s?format=%s" % (self.id, resource, fmt)
        tmp = dest + ".part"
        with self.client._request("GET", path) as r, open(tmp, "wb") as f:
            while True:
                chunk = r.read(1 << 16)
                if not chunk:
                    break
                f.write(chunk)
        os.replace(tmp, dest)

    def results(self, directory, formats=DEFAULT_FORMATS):
        """Downloads the result set into directory (created if missing): the
        files of `shapematch fetch --format formats`, history.csv and
        summary.json (the daemon's results document)."""
        os.makedirs(directory, exist_ok=True)
        for fmt in [f.strip() for f in formats.split(",") if f.strip()]:
            if fmt not in _FILES:
                raise ValueError("formats: unknown format %r (%s)" % (fmt, ", ".join(_FILES)))
            resource, q, name = _FILES[fmt]
            self._download(resource, q, os.path.join(directory, name))
        self._download("history", "csv", os.path.join(directory, "history.csv"))
        summary = self.client._json("GET", "/v1/jobs/%s/results" % self.id)
        with open(os.path.join(directory, "summary.json.part"), "w") as f:
            json.dump(summary, f, indent=2)
        os.replace(os.path.join(directory, "summary.json.part"),
                   os.path.join(directory, "summary.json"))
        return summary


class RemoteResult:
    """A successful job's results: summary (dict), history, warnings, status,
    converged; vertices, elements and displacement are read from the
    downloaded mesh when first asked for (through the library);
    write(dir) downloads the result set."""

    def __init__(self, job):
        self.job = job
        self.summary = job.client._json("GET", "/v1/jobs/%s/results" % job.id)
        self.status = "finished"
        self.converged = bool(self.summary.get("converged"))
        self.warnings = self.summary.get("warnings", [])
        # the two-sided figures, as Result.distance (None in older summaries)
        self.distance = self.summary.get("distance")
        with job.client._request("GET", "/v1/jobs/%s/results/history?format=json" % job.id) as r:
            self.history = json.loads(r.read().decode())
        self._mesh = None

    def write(self, directory, formats=DEFAULT_FORMATS):
        return self.job.results(directory, formats)

    def __repr__(self):
        from . import _headline
        return "<shapematch.RemoteResult of job %s: %s>" % (self.job.id, _headline(self.summary))

    def _load(self):
        if self._mesh is None:
            import tempfile
            from . import _read_mesh
            with tempfile.TemporaryDirectory(prefix="shapematch-") as d:
                p = os.path.join(d, "result.meshb")
                self.job._download("mesh", "meshb", p)
                q = os.path.join(d, "displacement.solb")
                self.job._download("displacement", "solb", q)
                self._mesh = _read_mesh(p, q)
        return self._mesh

    vertices = property(lambda self: self._load()["vertices"])
    elements = property(lambda self: self._load()["elements"])
    element_refs = property(lambda self: self._load()["element_refs"])
    displacement = property(lambda self: self._load()["displacement"])
