"""shapematch: elastic shape matching from Python.

    import shapematch
    r = shapematch.match("template.mesh", target_mesh="background.mesh.gz",
                         target_sol="background.sol.gz", clamp_ball=(0.5, 0.5, 0.04))
    r.vertices, r.displacement, r.summary["boundary_rms"]

The job runs in this process through ctypes on libshapematch_job.so (the
one job runner of `shapematch run`: the same checks, the same run, the
same vertices bit for bit); the keyword parameters are the params
document's members (docs/user-guide.md's table, `shapematch.parameters()`),
checked by the library's one parameter table.  Client talks to a daemon
(standard library only; Client.submit, Client.batch, Client.warp, and the
Job, Batch and RemoteResult they give: help(shapematch.Client)).
shapematch.__version__ is the library's release.  docs/python.md has the
whole story.
"""
import ctypes
import math
import os

from . import _arrays, _lib

__all__ = ["match", "batch", "sdf", "warp", "parameters", "Result", "ShapematchError", "Client", "Job",
           "Batch", "RemoteResult", "HTTPError", "__version__"]


def __getattr__(name):
    # the client (urllib, http.client: ~0.1 s to import) only when used
    if name in ("Client", "Job", "Batch", "RemoteResult", "HTTPError"):
        from . import _client
        return getattr(_client, name)
    if name == "__version__":
        # the library's (the Makefile's VERSION, written once): loaded now
        return _lib.job().sm_run_version().decode()
    raise AttributeError("module 'shapematch' has no attribute %r" % name)


class ShapematchError(RuntimeError):
    """The library refused the job or the run failed; str() is the core's
    message (naming the file, and its line, where there is one).  status:
    "format", "invalid", "numeric", "io", "nomem", or "failed" for a run
    that could not take a single step (result then holds the state)."""

    def __init__(self, message, status, result=None):
        super().__init__(message)
        self.status = status
        self.result = result


def _raise(err, status):
    msg = err.msg.decode("utf-8", "replace")
    raise ShapematchError(msg, _lib.STATUS_NAMES.get(status, str(status)))


def parameters():
    """The parameter table (sm_params_table): one dict per params member,
    name, flag, default, help and group (the section a form shows it in:
    inputs, clamp, stop or advanced), in the order of the params
    document."""
    lib = _lib.core()

    class Info(ctypes.Structure):
        _fields_ = [("name", ctypes.c_char_p), ("type", ctypes.c_int),
                    ("offset", ctypes.c_size_t), ("count_offset", ctypes.c_size_t),
                    ("min", ctypes.c_double), ("max", ctypes.c_double),
                    ("min_open", ctypes.c_int), ("max_open", ctypes.c_int),
                    ("default", ctypes.c_double), ("default_text", ctypes.c_char_p),
                    ("in_clamp", ctypes.c_int), ("flag", ctypes.c_char_p),
                    ("meta", ctypes.c_char_p), ("help", ctypes.c_char_p),
                    ("group", ctypes.c_char_p)]
    lib.sm_params_table.restype = ctypes.POINTER(Info)
    lib.sm_params_table.argtypes = [ctypes.POINTER(ctypes.c_size_t)]
    n = ctypes.c_size_t()
    rows = lib.sm_params_table(ctypes.byref(n))
    types = {0: "real", 1: "int", 2: "solver", 3: "refs", 4: "clamp"}
    dec = lambda b: b.decode() if b is not None else None  # noqa: E731
    return [{"name": dec(r.name), "type": types.get(r.type, str(r.type)), "min": r.min,
             "max": r.max, "default": dec(r.default_text) or r.default,
             "in_clamp": bool(r.in_clamp), "flag": dec(r.flag), "help": dec(r.help),
             "group": dec(r.group) or "advanced"}
            for r in (rows[i] for i in range(n.value))]


# ------------------------------------------------------------ arrays in memory

def _mesh_parts(m, what):
    """(vertices, elements, element_refs, vertex_refs, facets, facet_refs) of
    a mesh given as a tuple (vertices, elements[, element_refs]), a dict
    with those keys (and vertex_refs, facets, facet_refs) or a Result."""
    if isinstance(m, Result):
        return (m.vertices, m.elements, m.element_refs, m.vertex_refs, None, None)
    if isinstance(m, dict):
        unknown = set(m) - {"vertices", "elements", "element_refs", "vertex_refs", "facets",
                            "facet_refs"}
        if unknown:
            raise TypeError("%s: unknown keys %s" % (what, ", ".join(sorted(unknown))))
        return tuple(m.get(k) for k in ("vertices", "elements", "element_refs", "vertex_refs",
                                        "facets", "facet_refs"))
    if isinstance(m, (tuple, list)) and len(m) in (2, 3):
        return (m[0], m[1], m[2] if len(m) == 3 else None, None, None, None)
    if hasattr(m, "vertices") and hasattr(m, "elements"):  # a Client's result
        return (m.vertices, m.elements, getattr(m, "element_refs", None), None, None, None)
    raise TypeError("%s: expected a path, a (vertices, elements[, element_refs]) tuple, a dict "
                    "or a Result" % what)


def _pointer(a, ctype, keep):
    """A C pointer into array.array a (None when empty); keep holds the
    view alive while the library reads it."""
    if not len(a):
        return None
    view = (ctype * len(a)).from_buffer(a)
    keep.append(view)
    return ctypes.cast(view, ctypes.POINTER(ctype))


def _run_mesh(m, what, keep):
    """sm_run_mesh over the arrays of m (_mesh_parts' forms); the library
    checks the values (finite, indices naming a vertex) and copies them."""
    verts, elems, erefs, vrefs, facets, frefs = _mesh_parts(m, what)
    v, nv, dim = _arrays.doubles(verts, what + " vertices", cols=(2, 3))
    e, ne, _ = _arrays.int32s(elems, what + " elements", cols=(dim + 1,))
    f, nf = (None, 0)
    if facets is not None:
        f, nf, _ = _arrays.int32s(facets, what + " facets", cols=(dim,))
    rm = _lib.RunMesh(dim=dim, nverts=nv, nelems=ne, nfacets=nf)
    rm.coords = _pointer(v, ctypes.c_double, keep)
    rm.elems = _pointer(e, ctypes.c_int32, keep)
    if f is not None:
        rm.facets = _pointer(f, ctypes.c_int32, keep)
    for arr, n, field, name in ((erefs, ne, "elem_refs", "element_refs"),
                                (vrefs, nv, "vert_refs", "vertex_refs"),
                                (frefs, nf, "facet_refs", "facet_refs")):
        if arr is not None and n:
            a, rows, _ = _arrays.int32s(arr, "%s %s" % (what, name), cols=(0,))
            if rows != n:
                raise ValueError("%s %s: %d values for %d entries" % (what, name, rows, n))
            setattr(rm, field, _pointer(a, ctypes.c_int32, keep))
    keep.append(rm)
    return ctypes.pointer(rm)


def _run_surface(surface, what, keep):
    """sm_run_surface over (vertices, faces) arrays (or a dict with those
    keys): triangles in 3D, segments in 2D, 0-based."""
    if isinstance(surface, dict):
        unknown = set(surface) - {"vertices", "faces"}
        if unknown or "vertices" not in surface or "faces" not in surface:
            raise TypeError("%s: a dict with the keys vertices and faces is expected" % what)
        surface = (surface["vertices"], surface["faces"])
    if not (isinstance(surface, (tuple, list)) and len(surface) == 2):
        raise TypeError("%s: expected a path (STL, OBJ, PLY, OFF, VTK, Medit, Gmsh) or "
                        "(vertices, faces) arrays" % what)
    v, nv, dim = _arrays.doubles(surface[0], what + " vertices", cols=(2, 3))
    f, nf, _ = _arrays.int32s(surface[1], what + " faces", cols=(dim,))
    rs = _lib.RunSurface(dim=dim, nverts=nv, nfacets=nf)
    rs.coords = _pointer(v, ctypes.c_double, keep)
    rs.facets = _pointer(f, ctypes.c_int32, keep)
    keep.append(rs)
    return ctypes.pointer(rs)


def _read_mesh(mesh_path, sol_path=None):
    """vertices, elements (0-based), element_refs of a mesh file and the
    vector field of a sol file (the client's downloads), as arrays."""
    core = _lib.core()
    mesh = ctypes.POINTER(_lib.Mesh)()
    sol = ctypes.POINTER(_lib.Sol)()
    err = _lib.Error()
    try:
        st = core.sm_mesh_read(os.fsencode(mesh_path), ctypes.byref(mesh), ctypes.byref(err))
        if st:
            _raise(err, st)
        m = mesh.contents
        e = _arrays.out(m.elems, ctypes.c_int32, m.nelems, m.dim + 1)
        out = {"vertices": _arrays.out(m.coords, ctypes.c_double, m.nverts, m.dim),
               "elements": e, "element_refs": _arrays.out(m.elem_refs, ctypes.c_int32,
                                                           m.nelems, 0)}
        if sol_path is not None:
            st = core.sm_sol_read(os.fsencode(sol_path), ctypes.byref(sol), ctypes.byref(err))
            if st:
                _raise(err, st)
            s = sol.contents
            out["displacement"] = _arrays.out(s.values, ctypes.c_double, s.nverts, s.ncomp)
        return out
    finally:
        if mesh:
            core.sm_mesh_free(mesh)
        if sol:
            core.sm_sol_free(sol)


def _is_path(x):
    return isinstance(x, (str, bytes, os.PathLike))


# ------------------------------------------------------------ the result

class Result:
    """A job's outcome: vertices (final positions, nverts x dim), elements
    (0-based, nelems x dim+1), element_refs, vertex_refs, initial_vertices,
    displacement (vertices - initial_vertices), summary (summary.json as a
    dict), history (one dict per iteration), warnings, status ("finished",
    "cancelled", "failed"), exit_code (`shapematch run`'s), converged,
    distance (summary.json's "distance": {"result_to_target": {"rms",
    "max", "mean"}, "target_to_result": {"rms", "max", "mean", "p99"},
    "unit", "method"}, the headline figures in the meshes' unit; None for a
    summary without them); write(dir) writes the result set."""

    def __init__(self, handle):
        job = _lib.job()
        self._handle = handle
        dim, nv, ne = job.sm_run_dim(handle), job.sm_run_nverts(handle), job.sm_run_nelems(handle)
        d = ctypes.c_double
        i32 = ctypes.c_int32
        # copied now (close() may come first), made arrays when first read
        # (__getattr__): numpy is imported only then
        self._raw = {"vertices": _arrays.raw(job.sm_run_coords(handle), d, nv, dim),
                     "initial_vertices": _arrays.raw(job.sm_run_init_coords(handle), d, nv, dim),
                     "elements": _arrays.raw(job.sm_run_elems(handle), i32, ne, dim + 1),
                     "element_refs": _arrays.raw(job.sm_run_elem_refs(handle), i32, ne, 0),
                     "vertex_refs": _arrays.raw(job.sm_run_vert_refs(handle), i32, nv, 0)}
        text = job.sm_run_summary(handle)
        if text is None:
            raise MemoryError("shapematch: out of memory writing the summary")
        self._summary_text = text.decode()  # parsed when first read: json imports re
        self.status = job.sm_run_outcome(handle).decode()
        self.exit_code = job.sm_run_exit_code(handle)
        n = ctypes.c_size_t()
        rows = job.sm_run_history(handle, ctypes.byref(n))
        self.history = [_lib.progress_row(rows[i]) for i in range(n.value)]

    def __getattr__(self, name):
        raw = self.__dict__.get("_raw")
        if raw is None:
            raise AttributeError(name)
        if name in raw:
            value = _arrays.wrap(raw[name])
        elif name == "displacement":
            value = _arrays.minus(self.vertices, self.initial_vertices)
        elif name == "summary":
            import json
            value = json.loads(self._summary_text)
        elif name == "converged":
            value = bool(self.summary.get("converged"))
        elif name == "warnings":
            value = self.summary.get("warnings", [])
        elif name == "distance":
            value = self.summary.get("distance")
        else:
            raise AttributeError("'Result' object has no attribute %r" % name)
        self.__dict__[name] = value
        return value

    def write(self, directory, formats=None):
        """Writes the result set into directory (created if missing): the
        files of `shapematch run --format formats` (default "mesh,vtu,sol"),
        summary.json and history.csv/.json."""
        if self._handle is None:
            raise ValueError("shapematch: this Result was closed")
        err = _lib.Error()
        st = _lib.job().sm_run_write(self._handle, os.fsencode(directory),
                                     formats.encode() if formats else None, ctypes.byref(err))
        if st:
            _raise(err, st)

    def warp(self, **kw):
        """shapematch.warp(self, **kw): points, a mesh or a field through
        this result's map (points=, mesh=, field=, inverse=, strict=,
        normalize=, output=; see help(shapematch.warp))."""
        return warp(self, **kw)

    def to_meshio(self):
        """The deformed mesh as a meshio.Mesh (needs python3-meshio), with the
        displacement as point data and the element references as cell data."""
        import meshio
        kind = "triangle" if len(self.vertices[0]) == 2 else "tetra"
        return meshio.Mesh(_arrays.rows_of(self.vertices), [(kind, _arrays.rows_of(self.elements))],
                           point_data={"displacement": _arrays.rows_of(self.displacement)},
                           cell_data={"ref": [_arrays.rows_of(self.element_refs)]})

    def close(self):
        """Frees the library's side (inputs, target field) now; the arrays
        and the summary stay, write() no longer works."""
        if self._handle is not None:
            _lib.job().sm_run_free(self._handle)
            self._handle = None

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self):
        s = self.summary
        return "<shapematch.Result %s after %s iterations, %s%s>" % (
            self.status, s.get("iterations"), _headline(s),
            "" if self.converged else ", not converged")


def _headline(s):
    """The figures of a summary by their names there: the two-sided
    distances (RMS, max; p99 from the target) when it has them, else the
    RMS and max of d on the boundary; the L2 norm under its own name."""
    def num(x):
        return "%.3e" % x if isinstance(x, (int, float)) else "n/a"
    d = s.get("distance")
    if isinstance(d, dict) and "result_to_target" in d and "target_to_result" in d:
        a, b = d["result_to_target"], d["target_to_result"]
        text = "result->target RMS %s, max %s; target->result RMS %s, max %s, p99 %s" % (
            num(a.get("rms")), num(a.get("max")), num(b.get("rms")), num(b.get("max")),
            num(b.get("p99")))
        if d.get("unit"):
            text += " (%s)" % d["unit"]
    else:
        text = "boundary RMS %s, max %s" % (num(s.get("boundary_rms")), num(s.get("boundary_max")))
    return text + "; L2 of d on the boundary %s" % num(s.get("boundary_l2"))


# ------------------------------------------------------------ match

def _clamp(clamp_ball, clamp_elements, clamp_vertices, no_clamp, params):
    given = [n for n, v in (("clamp_ball", clamp_ball), ("clamp_elements", clamp_elements),
                            ("clamp_vertices", clamp_vertices)) if v is not None]
    if no_clamp:
        given.append("no_clamp")
    if not given:
        return {"kind": "auto"}  # the default ball at the template's deepest point
    if len(given) != 1:
        raise TypeError("shapematch.match: give at most one of clamp_ball, clamp_elements, "
                        "clamp_vertices, no_clamp=True (got %s)" % ", ".join(given))
    if clamp_ball is not None:
        b = [float(x) for x in clamp_ball]
        if len(b) not in (3, 4):
            raise ValueError("clamp_ball: expected (x, y, r) or (x, y, z, r) (got %d numbers)"
                             % len(b))
        return {"kind": "ball", "center": b[:-1], "radius": b[-1]}
    if no_clamp:
        clamp = {"kind": "none"}
        for row in parameters():  # alpha and any other member of the clamp
            if row["in_clamp"] and row["name"] in params:
                clamp[row["name"]] = params.pop(row["name"])
        return clamp
    refs = clamp_elements if clamp_elements is not None else clamp_vertices
    # a list, or one reference: a (numpy) int or a physical name ("core")
    refs = [refs] if isinstance(refs, (str, bytes)) or not hasattr(refs, "__iter__") else list(refs)
    return {"kind": "elements" if clamp_elements is not None else "vertices", "refs": refs}


_JSON_ESCAPES = {'"': '\\"', "\\": "\\\\", "\n": "\\n", "\r": "\\r", "\t": "\\t",
                 "\b": "\\b", "\f": "\\f"}


def _json_string(s):
    out = []
    for ch in s:
        o = ord(ch)
        if ch in _JSON_ESCAPES:
            out.append(_JSON_ESCAPES[ch])
        elif 0x20 <= o < 0x7f:
            out.append(ch)
        elif o > 0xffff:  # a surrogate pair, as json.dumps(ensure_ascii=True)
            o -= 0x10000
            out.append("\\u%04x\\u%04x" % (0xd800 | (o >> 10), 0xdc00 | (o & 0x3ff)))
        else:
            out.append("\\u%04x" % o)
    return '"' + "".join(out) + '"'


def _json(x):
    """json.dumps(x) for the params document (numbers, strings, booleans,
    None, lists, dicts, numpy values by tolist()), without importing json:
    its import (re with it) is a tenth of a 2D match's start-up over the
    command's (bench/python.sh).  tests/python checks it against json."""
    if x is None:
        return "null"
    if x is True or x is False:
        return "true" if x else "false"
    if isinstance(x, int):
        return int.__repr__(x)
    if isinstance(x, float):
        if x != x:
            return "NaN"
        if math.isinf(x):
            return "Infinity" if x > 0 else "-Infinity"
        return float.__repr__(x)
    if isinstance(x, str):
        return _json_string(x)
    if isinstance(x, (list, tuple)):
        return "[" + ", ".join(_json(v) for v in x) + "]"
    if isinstance(x, dict):
        for k in x:
            if not isinstance(k, str):
                raise TypeError("keys must be str, not %s" % type(k).__name__)
        return "{" + ", ".join(_json_string(k) + ": " + _json(v) for k, v in x.items()) + "}"
    if hasattr(x, "tolist"):
        return _json(x.tolist())
    raise TypeError("not a JSON value: %r" % (x,))


def match(template=None, *, target_mesh=None, target_sol=None, target_surface=None,
          target_image=None, clamp_ball=None, clamp_elements=None, clamp_vertices=None, no_clamp=False,
          progress=None, template_surface=None, template_image=None, template_label=None,
          **params):
    """Deforms template onto the target; returns a Result.

    template, target_mesh: a path (Medit .mesh/.meshb, Gmsh .msh, .gz) or
    arrays (vertices, elements[, element_refs]) (or a dict, or a Result);
    or, in place of template, template_surface: a closed surface (a path
    as target_surface, or arrays (vertices, facets)) or template_image: a
    label map's path with template_label=N, meshed by nglib
    (template_size=H: the element size; docs/your-data.md): how in
    result.summary["template"]["meshed"], the mesh written by write() as
    template.mesh;
    target_sol: a path or the distance at the target_mesh vertices (1-D);
    target_surface: a path (STL, OBJ, Medit, Gmsh); target_image: a path
    to a label map (NIfTI .nii/.nii.gz, NRRD .nrrd/.nhdr, MetaImage
    .mha/.mhd) whose voxels the params label=N, level=L and
    image_space="lps"|"ras" select and place, as `shapematch run
    --target-image` (docs/user-guide.md, "Targets from label maps").  At most one clamp
    (none: a ball at the template's deepest point, reported by the
    clamp-default warning):
    clamp_ball=(x, y[, z], r), clamp_elements=REFS, clamp_vertices=REFS or
    no_clamp=True (then alpha=...).  params: the params document's members
    (max_iter=200, young=..., free_boundary=[...]; shapematch.parameters()).
    progress(iteration, J, boundary_l2) is called after every iteration;
    returning False stops the run (status "cancelled", the state reached).
    Raises ShapematchError with the library's message."""
    doc = dict(params)
    doc["clamp"] = _clamp(clamp_ball, clamp_elements, clamp_vertices, no_clamp, doc)
    params_json = _json(doc).encode()
    rf = _lib.RunFiles()
    keep = []  # the arrays rf points into, alive until the library copied them
    if sum(x is not None for x in (template, template_surface, template_image)) != 1:
        raise TypeError("give one template: template, template_surface or template_image")
    if template_label is not None and template_image is None:
        raise TypeError("template_label is the label of template_image")
    if template_image is not None:
        if not _is_path(template_image):
            raise TypeError("template_image: give a path (NIfTI, NRRD, MetaImage)")
        rf.template_image = os.fsencode(template_image)
        rf.template_label = int(template_label or 0)
    if template_surface is not None:
        if _is_path(template_surface):
            rf.template_surface = os.fsencode(template_surface)
        else:
            rf.template_surface_arrays = _run_surface(template_surface, "template_surface", keep)
    for part, value in (("template", template), ("target_mesh", target_mesh),
                        ("target_sol", target_sol), ("target_surface", target_surface),
                        ("target_image", target_image)):
        if value is None:
            continue
        if _is_path(value):
            setattr(rf, "template_mesh" if part == "template" else part, os.fsencode(value))
        elif part == "target_image":
            raise TypeError("target_image: give a path (NIfTI, NRRD, MetaImage)")
        elif part == "target_sol":
            a, n, _ = _arrays.doubles(value, part, cols=(0,))
            rf.target_sol_values = _pointer(a, ctypes.c_double, keep)
            rf.target_sol_count = n
        elif part == "target_surface":
            rf.target_surface_arrays = _run_surface(value, part, keep)
        else:
            setattr(rf, part + "_arrays", _run_mesh(value, part, keep))
    return _run(rf, params_json, progress)


def _run(rf, params_json, progress):
    job = _lib.job()
    caught = []

    def on_progress(p, _user):
        # also where Ctrl-C lands: the signal is seen when Python code runs
        try:
            if progress is not None:
                q = p.contents
                return 0 if progress(q.iteration, q.J, q.boundary_l2) is not False else 1
            return 0
        except BaseException as e:  # re-raised after the run stopped
            caught.append(e)
            return 1

    cb = _lib.PROGRESS_FN(on_progress)
    handle = ctypes.c_void_p()
    err = _lib.Error()
    # ctypes releases the GIL for the call: other threads run meanwhile
    st = job.sm_run_job(ctypes.byref(rf), params_json, cb, None, None, ctypes.byref(handle),
                        ctypes.byref(err))
    if st:
        if caught:
            raise caught[0]
        _raise(err, st)
    result = Result(handle.value)
    if caught:
        result.close()
        raise caught[0]
    if result.status == "failed":
        raise ShapematchError(job.sm_run_message(handle.value).decode(), "failed", result)
    return result


# ------------------------------------------------------------ batch

_LIST_COLUMNS = ("name", "target_surface", "target_mesh", "target_sol", "landmarks")


def _target_dict(t):
    if _is_path(t):
        return {"target_surface": t}
    if isinstance(t, (tuple, list)) and len(t) == 2:
        return {"target_mesh": t[0], "target_sol": t[1]}
    if not isinstance(t, dict):
        raise TypeError("a target is a path, a (mesh, sol) pair or a dict: %r" % (t,))
    unknown = set(t) - set(_LIST_COLUMNS) - {"target_image"}
    if unknown:
        raise TypeError("a target's keys are %s, target_image (got %s)"
                        % (", ".join(_LIST_COLUMNS), ", ".join(sorted(unknown))))
    return t


def _target_row(t, columns):
    """One LIST.csv row of a target (a dict, _target_dict's), its values
    in the order of columns."""
    row = []
    for key in columns:
        v = t.get(key)
        v = "" if v is None else os.fsdecode(v)
        if key != "name" and v:
            v = os.path.abspath(v)
        if any(c in v for c in ",\r\n"):
            raise ValueError("%s: a comma or line break cannot be listed: %r" % (key, v))
        row.append(v)
    return ",".join(row)


def batch(template, targets, out_dir, *, clamp_ball=None, clamp_elements=None,
          clamp_vertices=None, no_clamp=False, model_align="rigid", jobs=None,
          template_from=None, rounds=None, template_tolerance=None, **params):
    """Matches template onto every target, the template side set up once,
    then builds their shape model (docs/populations.md); returns the
    batch's summary (out_dir/summary.json) as a dict, with the model's
    summary under "model_summary" when it was built.

    template: a path; targets: a list of paths (surfaces), (mesh, sol)
    pairs or dicts (name, target_surface, target_mesh, target_sol,
    landmarks, target_image: a label map, selected by the params label,
    level, image_space as in match(); its list column needs a library
    whose LIST.csv reader knows target_image); out_dir: the folder (targets/NAME/, model/, summary.json).
    The clamp and params as in match(); model_align: "none", "rigid" or
    "similarity"; jobs: targets at a time (None: the CPUs).  A target that
    fails is listed in "failed" and left out of the model; errors of the
    template, the parameters or the list raise ShapematchError.

    template_from (`shapematch batch --template-from`): "medoid" or
    "mean" start from template and choose the next round's template from
    the population (the medoid's result mesh; the model's mean, at most
    rounds rounds, default 3, until it moves less than
    template_tolerance of its size, default 1e-3); "file" is template
    itself, named in the summaries.  The summary's "template_from" says
    how it ended (rounds, movement, medoid); each round's batch is in
    out_dir/rounds/K/."""
    doc = dict(params)
    doc["clamp"] = _clamp(clamp_ball, clamp_elements, clamp_vertices, no_clamp, doc)
    params_json = _json(doc).encode()
    targets = [_target_dict(t) for t in targets]
    columns = _LIST_COLUMNS
    # the target_image column only when a target has one: a list without
    # it is read by every version of the library
    if any(t.get("target_image") is not None for t in targets):
        columns += ("target_image",)
    rows = [",".join(columns)] + [_target_row(t, columns) for t in targets]
    text = ("\n".join(rows) + "\n").encode()
    err = _lib.Error()
    if template_from is None and (rounds is not None or template_tolerance is not None):
        raise TypeError("batch: rounds and template_tolerance go with template_from=\"mean\"")
    st = _lib.job().sm_run_batch_from(
        os.fsencode(template), template_from.encode() if template_from else None,
        int(rounds or 0), float(template_tolerance or 0), text, len(text), params_json,
        model_align.encode() if model_align else None, int(jobs or 0), os.fsencode(out_dir),
        ctypes.byref(err))
    if st:
        _raise(err, st)
    import json  # here only: its import is a cost match() does not pay
    with open(os.path.join(out_dir, "summary.json")) as f:
        summary = json.load(f)
    if summary.get("model"):
        with open(os.path.join(out_dir, "model", "summary.json")) as f:
            summary["model_summary"] = json.load(f)
    return summary


# ------------------------------------------------------------ sdf

def sdf(surface, points):
    """Signed distance (negative inside) from a surface to points, exact
    (sm_sdf.h), after the surface is repaired (oriented consistently and
    outward) like `shapematch sdf` does.  surface: a path (STL, OBJ,
    Medit, Gmsh) or (vertices, facets) arrays (0-based triangles in 3D,
    segments in 2D); points: an (n, dim) array, or a mesh path (its
    vertices).  Returns n distances."""
    core = _lib.core()
    err = _lib.Error()
    surf = ctypes.POINTER(_lib.Surface)()
    mesh = ctypes.POINTER(_lib.Mesh)()
    d = ctypes.c_void_p()
    try:
        if _is_path(surface):
            st = core.sm_surface_read(os.fsencode(surface), ctypes.byref(surf), ctypes.byref(err))
            if st:
                _raise(err, st)
        else:
            v, nv, dim = _arrays.doubles(surface[0], "surface vertices", cols=(2, 3))
            f, nf, _ = _arrays.int32s(surface[1], "surface facets", cols=(dim,))
            if any(not 0 <= x < nv for x in f):
                raise ValueError("surface facets: a vertex index is out of range [0, %d)" % nv)
            st = core.sm_surface_alloc(ctypes.byref(surf), dim, nv, nf, ctypes.byref(err))
            if st:
                _raise(err, st)
            _arrays.copy_into(surf.contents.coords, v)
            _arrays.copy_into(surf.contents.facets, f)
        dim = surf.contents.dim
        if _is_path(points):
            st = core.sm_mesh_read(os.fsencode(points), ctypes.byref(mesh), ctypes.byref(err))
            if st:
                _raise(err, st)
            n, pdim, ptr = mesh.contents.nverts, mesh.contents.dim, mesh.contents.coords
        else:
            p, n, pdim = _arrays.doubles(points, "points", cols=(2, 3))
            ptr = (ctypes.c_double * max(len(p), 1)).from_buffer(p) if len(p) else \
                (ctypes.c_double * 1)()
        if pdim != dim:
            raise ValueError("points are %dD and the surface %dD" % (pdim, dim))
        health = _lib.SurfaceHealth()
        for st in (core.sm_surface_repair(surf, ctypes.byref(health), ctypes.byref(err)),
                   core.sm_sdf_new(surf, ctypes.byref(d), ctypes.byref(err))):
            if st:
                _raise(err, st)
        out = (ctypes.c_double * max(n, 1))()
        st = core.sm_sdf_signed(d, n, ctypes.cast(ptr, ctypes.POINTER(ctypes.c_double)), out,
                                ctypes.byref(err))
        if st:
            _raise(err, st)
        return _arrays.out(out, ctypes.c_double, n, 0)
    finally:
        if d.value:
            core.sm_sdf_free(d)
        if surf:
            core.sm_surface_free(surf)
        if mesh:
            core.sm_mesh_free(mesh)


# ------------------------------------------------------------ warp

def warp(result, *, points=None, mesh=None, field=None, inverse=False, strict=False,
         normalize=False, output=None, outside="extrapolate"):
    """Carries points, a mesh or a field through the map of a finished
    match, forward (template -> target) or back with inverse=True, as
    `shapematch warp` does (docs/warp.md: the conventions).  result: a
    result folder (result.mesh + displacement.sol, as run, fetch and
    Result.write leave them), a Result, or a Client's result (a
    RemoteResult, from Job.wait(): its map is downloaded once and warped
    here; Client.warp asks the daemon instead).  Exactly one of:
      points  an (n, dim) array: returns (mapped (n, dim), inside (n,)
              0/1: 0 for a point outside the source mesh, mapped by its
              nearest element); strict=True raises ShapematchError for the
              first point outside instead ("point I (1-based) is outside");
              outside="flag" gives those NaN rows, outside="skip" leaves
              them out of mapped (inside still has one flag per point
              given: mapped's rows are the points whose flag is 1);
      mesh    a path (any mesh or surface `warp --mesh` reads) or arrays
              (vertices, elements): returns the moved vertices; with
              output=PATH (a path mesh only) writes it, the format by the
              name (.mesh/.meshb/.vtu, and for surfaces .stl .obj .ply .off
              .vtk);
      field   a .sol path or an (nverts, ncomp) array on the template's
              vertices (the result's with inverse): scalars kept, vectors
              by the deformation gradient F (normalize=True: unit length),
              symmetric tensors (xx, xy, yy[, xz, yz, zz]) as F T F^T;
              returns the carried values; output=PATH writes a .sol/.solb."""
    from . import _warp
    if hasattr(result, "_map_folder"):  # a Client's result: its files, downloaded once
        result = result._map_folder()
    return _warp.warp(result, _raise, points=points, mesh=mesh, field=field, inverse=inverse,
                      strict=strict, normalize=normalize, output=output, outside=outside)
