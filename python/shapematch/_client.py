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
import math
import os
import time
import urllib.error
import urllib.parse
import urllib.request
import uuid

FINAL = ("successful", "failed", "dismissed")
# Client.warp: a body's media type by its file's extension (proto/openapi.yaml)
_WARP_TYPES = {".mesh": "application/x-medit-mesh", ".msh": "application/x-medit-mesh",
               ".meshb": "application/x-medit-meshb", ".stl": "model/stl", ".obj": "model/obj",
               ".ply": "model/x-ply", ".off": "model/x-off", ".vtk": "application/x-vtk",
               ".vtu": "application/x-vtu", ".vtp": "application/x-vtu",
               ".sol": "application/x-medit-sol", ".solb": "application/x-medit-solb"}

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
        """The Job of that id (no request is made)."""
        return Job(self, job_id)

    def batch(self, template, targets, *, model_align="rigid", names=None, clamp_ball=None,
              clamp_elements=None, clamp_vertices=None, no_clamp=False, **params):
        """Matches template onto every target on the daemon, then builds
        their shape model (docs/api.md, "Batches"; shapematch.batch runs the
        same here): one job per target (submit(), the same clamp and
        params), grouped by POST /v1/batches.  targets: paths (surfaces),
        (mesh, sol) pairs or dicts (target_surface, target_mesh,
        target_sol, target_image, name); names: one per target (default:
        a dict's name, else the job id); model_align: "none", "rigid" or
        "similarity".  Returns the Batch; batch.wait() follows it."""
        from . import _target_dict
        jobs, entries = [], []
        for k, t in enumerate(targets):
            t = dict(_target_dict(t))
            name = names[k] if names is not None else t.pop("name", None)
            t.pop("name", None)
            if t.pop("landmarks", None) is not None:
                raise TypeError("Client.batch: landmarks are not sent to a daemon (the job "
                                "takes template and target landmarks as parts; use submit)")
            job = self.submit(template, clamp_ball=clamp_ball, clamp_elements=clamp_elements,
                              clamp_vertices=clamp_vertices, no_clamp=no_clamp,
                              **dict(params, **t))
            jobs.append(job)
            entries.append({"job": job.id} if name is None else {"job": job.id, "name": name})
        body = json.dumps({"targets": entries, "model_align": model_align or "rigid"}).encode()
        info = self._json("POST", "/v1/batches", body=body,
                          headers={"Content-Type": "application/json",
                                   "Accept": "application/json"})
        return Batch(self, info["batchID"], jobs)

    def warp(self, job, *, points=None, mesh=None, field=None, inverse=False, strict=False,
             normalize=False, output=None, outside="extrapolate"):
        """Carries points, a mesh or a field through a successful job's map
        on the daemon (POST /v1/jobs/{id}/warp; shapematch.warp does it
        here, on downloaded files).  job: a Job, a RemoteResult or a job id.
          points  an (n, dim) array: returns (mapped (n, dim), inside (n,));
                  strict=True raises HTTPError (422) for a point outside;
                  outside="flag" gives those NaN rows, "skip" leaves them out
                  of mapped (inside keeps one flag per point given);
          mesh    a path (Medit, Gmsh, VTK, or a surface: STL, OBJ, PLY,
                  OFF): the answer (vertices moved, topology kept) is
                  written to output=PATH, its format by the name
                  (.mesh, .vtu, .stl, .obj, .ply, .off, .vtk); returns PATH;
          field   a .sol/.solb path at the template's vertices: the carried
                  field written to output=PATH; returns PATH."""
        from . import _arrays
        job_id = getattr(getattr(job, "job", job), "id", job)
        given = [n for n, v in (("points", points), ("mesh", mesh), ("field", field))
                 if v is not None]
        if len(given) != 1:
            raise TypeError("Client.warp: give exactly one of points, mesh, field (got %s)"
                            % (", ".join(given) or "none"))
        query = {"direction": "inverse" if inverse else "forward"}
        if strict:
            query["strict"] = "true"
        if normalize:
            query["normalize"] = "true"
        if outside != "extrapolate":
            query["outside"] = outside
        path = "/v1/jobs/%s/warp" % job_id
        if points is not None:
            if output is not None:
                raise ValueError("Client.warp: output= is for a mesh or a field")
            a, n, dim = _arrays.doubles(points, "points", cols=(2, 3))
            rows = [list(a[i * dim:(i + 1) * dim]) for i in range(n)]
            body = json.dumps({"points": rows}).encode()
            doc = self._json("POST", path + "?" + urllib.parse.urlencode(query), body=body,
                             headers={"Content-Type": "application/json",
                                      "Accept": "application/json"})
            import array
            # a flagged point is null (JSON has no NaN); skipped ones are
            # not in the answer, whose inside then has one flag per row
            flat = array.array("d", (float(x) for p in doc["points"]
                                     for x in (p if p is not None else [math.nan] * dim)))
            kept = len(doc["points"])
            flags = [int(x) for x in doc["inside"]]  # one per point given
            inside = array.array("i", flags)
            return (_arrays.wrap((bytearray(flat.tobytes()), "d", kept, dim)),
                    _arrays.wrap((bytearray(inside.tobytes()), "i", len(flags), 0)))
        src = mesh if mesh is not None else field
        if output is None:
            raise ValueError("Client.warp: a mesh or a field needs output=PATH (the answer)")
        name = os.fsdecode(src)
        base = name[:-3] if name.endswith(".gz") else name
        ext = os.path.splitext(base)[1].lower()
        if ext not in _WARP_TYPES:
            raise ValueError("Client.warp: %s: send .mesh/.meshb/.msh/.vtk/.vtu, a surface "
                             "(.stl, .obj, .ply, .off) or a field (.sol, .solb)" % name)
        if (field is not None) != (ext in (".sol", ".solb")):
            raise ValueError("Client.warp: %s is not a %s" % (name, "field" if field is not None
                                                              else "mesh"))
        out_ext = os.path.splitext(os.fsdecode(output))[1].lstrip(".").lower()
        if mesh is not None and out_ext in ("mesh", "vtu", "stl", "obj", "ply", "off", "vtk"):
            query["format"] = out_ext
        with open(src, "rb") as f:
            body = f.read()
        tmp = os.fsdecode(output) + ".part"
        with self._request("POST", path + "?" + urllib.parse.urlencode(query), body=body,
                           headers={"Content-Type": _WARP_TYPES[ext]}) as r, \
                open(tmp, "wb") as f:
            f.write(r.read())
        os.replace(tmp, output)
        return output


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
        return _follow(self.client, "/v1/jobs/%s/events" % self.id, after)

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
    write(dir) downloads the result set; warp(...) carries points, a mesh
    or a field through its map (shapematch.warp, here on the downloaded
    files); close() removes the downloaded files (else when the object
    goes)."""

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
        self._dir = None

    def __repr__(self):
        from . import _headline
        return "<shapematch.RemoteResult of job %s: %s>" % (self.job.id, _headline(self.summary))

    def write(self, directory, formats=DEFAULT_FORMATS):
        """Downloads the result set into directory (Job.results)."""
        return self.job.results(directory, formats)

    def _map_folder(self):
        """A private folder with result.meshb and displacement.solb, downloaded
        once: the map shapematch.warp reads."""
        if self._dir is None:
            import tempfile
            d = tempfile.mkdtemp(prefix="shapematch-remote-")
            try:
                self.job._download("mesh", "meshb", os.path.join(d, "result.meshb"))
                self.job._download("displacement", "solb", os.path.join(d, "displacement.solb"))
            except BaseException:
                import shutil
                shutil.rmtree(d, ignore_errors=True)
                raise
            self._dir = d
        return self._dir

    def _load(self):
        if self._mesh is None:
            from . import _read_mesh
            d = self._map_folder()
            self._mesh = _read_mesh(os.path.join(d, "result.meshb"),
                                    os.path.join(d, "displacement.solb"))
        return self._mesh

    def warp(self, **kw):
        """shapematch.warp(self, **kw): points, a mesh or a field through
        this result's map, computed here (see help(shapematch.warp))."""
        from . import warp
        return warp(self, **kw)

    def close(self):
        """Removes the downloaded files (the arrays read stay)."""
        if self._dir is not None:
            import shutil
            shutil.rmtree(self._dir, ignore_errors=True)
            self._dir = None

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass

    vertices = property(lambda self: self._load()["vertices"], doc="final positions")
    elements = property(lambda self: self._load()["elements"], doc="0-based elements")
    element_refs = property(lambda self: self._load()["element_refs"], doc="element references")
    displacement = property(lambda self: self._load()["displacement"],
                            doc="vertices - the template's")


class Batch:
    """A batch on the daemon: its targets' jobs and the model job (whose id
    is the batch's).  status() is GET /v1/batches/{id}; events() and
    wait() follow /v1/batches/{id}/events; model(dir) downloads the
    model's files."""

    def __init__(self, client, batch_id, jobs=()):
        self.client = client
        self.id = batch_id
        self.jobs = list(jobs)

    def __repr__(self):
        return "<shapematch.Batch %s of %d targets>" % (self.id, len(self.jobs))

    def status(self):
        """The batch document (dict: status, progress, eta, counts, targets,
        model)."""
        return self.client._json("GET", "/v1/batches/" + self.id)

    def cancel(self):
        """Cancels a live batch (its model job, then its targets), or
        deletes a final one; returns the batch document."""
        return self.client._json("DELETE", "/v1/batches/" + self.id)

    def events(self, after=0):
        """The batch's events as dicts ("target": one target changed,
        "batch": the whole batch's progress, "status": the last, with the
        batch document), followed live until the batch ends; resumes after
        a lost connection with Last-Event-ID."""
        return _follow(self.client, "/v1/batches/%s/events" % self.id, after)

    def wait(self, progress=None):
        """Follows the batch to its end; returns the final batch document.
        progress(event) is called with every "batch" event (progress, eta,
        counts).  Raises shapematch.ShapematchError when the model job did
        not succeed (its message names the targets left out)."""
        from . import ShapematchError
        doc = None
        for event in self.events():
            if event.get("type") == "batch" and progress is not None:
                progress(event)
            elif event.get("type") == "status":
                doc = event  # the batch document
        doc = doc if doc and "status" in doc else self.status()
        if doc.get("status") != "successful":
            raise ShapematchError("batch %s %s%s" % (
                self.id, doc.get("status", "ended"),
                ": " + doc["message"] if doc.get("message") else ""),
                "failed" if doc.get("status") == "failed" else "cancelled")
        return doc

    def model(self, directory):
        """Downloads the model's files (mean.mesh, mean.vtu, modes.vtu,
        scores.csv, summary.json, mode_K.sol) into directory (created if
        missing); returns the model's summary (dict)."""
        info = self.client._json("GET", "/v1/batches/%s/model" % self.id)
        os.makedirs(directory, exist_ok=True)
        for f in info.get("files", []):
            name = f["name"]
            if "/" in name or name.startswith("."):
                raise ValueError("batch model: unexpected file name %r" % name)
            dest = os.path.join(directory, name)
            with self.client._request("GET", "/v1/batches/%s/model/%s" % (self.id, name)) as r, \
                    open(dest + ".part", "wb") as out:
                out.write(r.read())
            os.replace(dest + ".part", dest)
        return info.get("summary")


def _follow(client, path, after):
    """The events of an SSE route (a job's or a batch's) as dicts, replayed
    then followed live until the closing "status" event; resumes after a
    lost connection with Last-Event-ID."""
    last = after
    while True:
        headers = {"Accept": "text/event-stream"}
        if last:
            headers["Last-Event-ID"] = str(last)
        try:
            with client._request("GET", path, headers=headers, stream=True) as r:
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
