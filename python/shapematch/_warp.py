"""shapematch.warp: points, meshes and fields through a result's map, the
job layer's warp use case (proto/job/sm_job_warp.h) through
libshapematch_job's sm_run_map_* and sm_run_warp_* (shapematch_job.h), as
`shapematch warp` and the daemon's warp route use it (docs/warp.md has the
conventions)."""
import ctypes
import os

from . import _arrays, _lib

_P = ctypes.POINTER


class _Map:
    """A map (sm_run_map): a result folder's, read by the library, or a
    Result's arrays."""

    def __init__(self, result, raise_):
        self.job = _lib.job()
        self.ptr = ctypes.c_void_p()
        err = _lib.Error()
        from . import Result  # the package's; imported here against a cycle
        if isinstance(result, Result):
            x, nv, dim = _arrays.doubles(result.initial_vertices, "result vertices", cols=(2, 3))
            y, _, _ = _arrays.doubles(result.vertices, "result vertices", cols=(dim,))
            e, ne, _ = _arrays.int32s(result.elements, "result elements", cols=(dim + 1,))
            st = self.job.sm_run_map_new(dim, nv, _doubles_ptr(x), _doubles_ptr(y), ne,
                                         _int32s_ptr(e), ctypes.byref(self.ptr),
                                         ctypes.byref(err))
        elif isinstance(result, (str, bytes, os.PathLike)):
            st = self.job.sm_run_map_open(os.fsencode(result), ctypes.byref(self.ptr),
                                          ctypes.byref(err))
        else:
            raise TypeError("warp: result is a result folder (path) or a Result")
        if st:
            raise_(err, st)

    @property
    def dim(self):
        return self.job.sm_run_map_dim(self.ptr)

    @property
    def nverts(self):
        return self.job.sm_run_map_nverts(self.ptr)

    def close(self):
        if self.ptr:
            self.job.sm_run_map_free(self.ptr)
            self.ptr = ctypes.c_void_p()


def _doubles_ptr(a):
    return ctypes.cast((ctypes.c_double * max(len(a), 1)).from_buffer(a) if len(a) else
                       (ctypes.c_double * 1)(), _P(ctypes.c_double))


def _int32s_ptr(a):
    return ctypes.cast((ctypes.c_int32 * max(len(a), 1)).from_buffer(a) if len(a) else
                       (ctypes.c_int32 * 1)(), _P(ctypes.c_int32))


_OUTSIDE = {"extrapolate": 0, "flag": 1, "skip": 2}


def _points(mp, direction, strict, points, what, raise_, outside="extrapolate"):
    """(out C array, inside C array, n, dim, rows of out) of an (n, dim)
    array."""
    xyz, n, dim = _arrays.doubles(points, what, cols=(2, 3))
    if dim != mp.dim:
        raise ValueError("warp: %dD %s and the map is %dD" % (dim, what, mp.dim))
    out = (ctypes.c_double * max(n * dim, 1))()
    inside = (ctypes.c_uint8 * max(n, 1))()
    nout = ctypes.c_int64()
    kept = ctypes.c_int64()
    err = _lib.Error()
    st = mp.job.sm_run_warp_points(mp.ptr, direction, 1 if strict else 0, _OUTSIDE[outside],
                                   dim, n, _doubles_ptr(xyz), out, inside, ctypes.byref(nout),
                                   ctypes.byref(kept), ctypes.byref(err))
    if st:
        raise_(err, st)
    return out, inside, n, dim, kept.value


def _file(mp, field, path, output, direction, strict, normalize, raise_):
    """The warped values of a mesh/surface (field False) or .sol file,
    written to output when given: an (rows, cols) array."""
    values = _P(ctypes.c_double)()
    rows, cols = ctypes.c_int64(), ctypes.c_int()
    err = _lib.Error()
    st = mp.job.sm_run_warp_file(mp.ptr, 1 if field else 0, os.fsencode(path),
                                 os.fsencode(output) if output is not None else None,
                                 direction, 1 if strict else 0, 1 if normalize else 0,
                                 ctypes.byref(values), ctypes.byref(rows), ctypes.byref(cols),
                                 ctypes.byref(err))
    if st:
        raise_(err, st)
    try:
        n, c = rows.value, cols.value
        copy = (ctypes.c_double * max(n * c, 1))()
        ctypes.memmove(copy, values, n * c * 8)
    finally:
        mp.job.sm_run_warp_values_free(values)
    return _arrays.out(copy, ctypes.c_double, n, c if (not field or c > 1) else 0)


def _field_array(mp, direction, normalize, field, output, raise_):
    """An (nverts, ncomp) array carried (and written to output when
    given): the carried values."""
    core = _lib.core()
    a, rows, cols = _arrays.doubles(field, "field", cols=None)
    ncomp = cols or 1
    err = _lib.Error()
    sol = _P(_lib.Sol)()
    st = core.sm_sol_alloc(ctypes.byref(sol), mp.dim, rows, ncomp, ctypes.byref(err))
    if st:
        raise_(err, st)
    try:
        _arrays.copy_into(sol.contents.values, a)
        st = mp.job.sm_run_warp_field(mp.ptr, direction, 1 if normalize else 0, mp.dim, rows,
                                      ncomp, sol.contents.values, ctypes.byref(err))
        if not st and output is not None:
            st = core.sm_sol_write(os.fsencode(output), sol, ctypes.byref(err))
        if st:
            raise_(err, st)
        return _arrays.out(sol.contents.values, ctypes.c_double, rows, ncomp if ncomp > 1 else 0)
    finally:
        core.sm_sol_free(sol)


def warp(result, raise_, points=None, mesh=None, field=None, inverse=False, strict=False,
         normalize=False, output=None, outside="extrapolate"):
    given = [x is not None for x in (points, mesh, field)]
    if sum(given) != 1:
        raise TypeError("warp: give exactly one of points=, mesh= and field=")
    if outside not in _OUTSIDE:
        raise ValueError("warp: outside= is 'extrapolate', 'flag' or 'skip', not %r" % (outside,))
    if outside != "extrapolate" and points is None:
        raise TypeError("warp: outside=%r is for points= (a mesh's vertices outside are "
                        "extrapolated, or refused with strict=True)" % outside)
    if outside != "extrapolate" and strict:
        raise TypeError("warp: give strict=True or outside=%r, not both" % outside)
    if normalize and field is None:
        raise TypeError("warp: normalize= is for field=")
    if output is not None and points is not None:
        raise TypeError("warp: output= is for mesh= and field= (points come back as arrays)")
    direction = 1 if inverse else 0
    mp = _Map(result, raise_)
    try:
        if points is not None:
            out, inside, n, dim, rows = _points(mp, direction, strict, points, "points",
                                                raise_, outside)
            flags = (ctypes.c_int32 * max(n, 1))(*inside[:n])
            return (_arrays.out(out, ctypes.c_double, rows, dim),
                    _arrays.out(flags, ctypes.c_int32, n, 0))
        if mesh is not None:
            if isinstance(mesh, (str, bytes, os.PathLike)):
                return _file(mp, False, mesh, output, direction, strict, False, raise_)
            if output is not None:
                raise ValueError("warp: output= is for a mesh given as a file (arrays come back)")
            verts = mesh[0] if isinstance(mesh, (tuple, list)) else mesh["vertices"]
            out, _, n, dim, _ = _points(mp, direction, strict, verts, "mesh vertices", raise_)
            return _arrays.out(out, ctypes.c_double, n, dim)
        if isinstance(field, (str, bytes, os.PathLike)):
            return _file(mp, True, field, output, direction, False, normalize, raise_)
        return _field_array(mp, direction, normalize, field, output, raise_)
    finally:
        mp.close()
