"""shapematch.warp: points, meshes and fields through a result's map, the
library's sm_warp (core/include/shapematch/sm_warp.h) through ctypes, as
`shapematch warp` uses it (docs/warp.md has the conventions)."""
import ctypes
import os

from . import _arrays, _lib

FORWARD, INVERSE = 0, 1
_MESHES = ("result.mesh", "result.meshb", "result.mesh.gz", "result.meshb.gz")
_SOLS = ("displacement.sol", "displacement.solb", "displacement.sol.gz", "displacement.solb.gz")


def _first(directory, names):
    for n in names:
        p = os.path.join(directory, n)
        if os.path.exists(p):
            return p
    return None


class _Map:
    """The template mesh (library-owned) and the deformed coordinates, as
    sm_job_map_read reads a result folder (template = result -
    displacement, the same arithmetic), or from a Result."""

    def __init__(self, result, raise_):
        core = _lib.core()
        self.core = core
        self.mesh = ctypes.POINTER(_lib.Mesh)()
        err = _lib.Error()
        from . import Result  # the package's; imported here against a cycle
        if isinstance(result, Result):
            self._from_result(result, raise_)
            return
        if not isinstance(result, (str, bytes, os.PathLike)):
            raise TypeError("warp: result is a result folder (path) or a Result")
        directory = os.fsdecode(result)
        pm, ps = _first(directory, _MESHES), _first(directory, _SOLS)
        if not pm or not ps:
            raise _lib_error(raise_, "%s has no %s (a result folder of 'run' or 'fetch')" % (
                directory, "result.mesh or result.meshb" if not pm else
                "displacement.sol or displacement.solb"), 1)
        sol = ctypes.POINTER(_lib.Sol)()
        try:
            st = core.sm_mesh_read(os.fsencode(pm), ctypes.byref(self.mesh), ctypes.byref(err))
            if not st:
                st = core.sm_sol_read(os.fsencode(ps), ctypes.byref(sol), ctypes.byref(err))
            if st:
                raise_(err, st)
            m, d = self.mesh.contents, sol.contents
            if d.nverts != m.nverts or d.ncomp != m.dim:
                raise _lib_error(raise_, "%s has %d values of %d components, %s %d vertices in "
                                 "%dD" % (ps, d.nverts, d.ncomp, pm, m.nverts, m.dim), 2)
            n = m.nverts * m.dim
            self.deformed = (ctypes.c_double * max(n, 1))()
            ctypes.memmove(self.deformed, m.coords, n * 8)
            _subtract(m.coords, d.values, n)
        except BaseException:
            self.close()
            raise
        finally:
            if sol:
                core.sm_sol_free(sol)

    def _from_result(self, r, raise_):
        core = self.core
        err = _lib.Error()
        x, nv, dim = _arrays.doubles(r.initial_vertices, "result vertices", cols=(2, 3))
        y, _, _ = _arrays.doubles(r.vertices, "result vertices", cols=(dim,))
        e, ne, _ = _arrays.int32s(r.elements, "result elements", cols=(dim + 1,))
        st = core.sm_mesh_alloc(ctypes.byref(self.mesh), dim, nv, ne, 0, ctypes.byref(err))
        if st:
            raise_(err, st)
        _arrays.copy_into(self.mesh.contents.coords, x)
        _arrays.copy_into(self.mesh.contents.elems, e)
        self.deformed = (ctypes.c_double * max(len(y), 1))()
        _arrays.copy_into(self.deformed, y)

    @property
    def dim(self):
        return self.mesh.contents.dim

    def close(self):
        if self.mesh:
            self.core.sm_mesh_free(self.mesh)
            self.mesh = ctypes.POINTER(_lib.Mesh)()


def _subtract(coords, values, n):
    """coords[i] -= values[i] for n doubles (C arrays), as sm_job_map_read."""
    np = _arrays._np()
    if np is not None and n:
        a = np.ctypeslib.as_array(coords, shape=(n,))
        a -= np.ctypeslib.as_array(values, shape=(n,))
        return
    for i in range(n):
        coords[i] -= values[i]


def _lib_error(raise_, msg, status):
    err = _lib.Error()
    err.msg = msg.encode()[:_lib.ERROR_MSG_LEN - 1]
    try:
        raise_(err, status)
    except Exception as e:  # noqa: BLE001 (returned for `raise`)
        return e


def _doubles_ptr(a):
    return ctypes.cast((ctypes.c_double * max(len(a), 1)).from_buffer(a) if len(a) else
                       (ctypes.c_double * 1)(), ctypes.POINTER(ctypes.c_double))


def _warp_points(core, w, direction, strict, ptr, n, dim, raise_):
    """(out C array, inside C array, noutside) of the n points at ptr."""
    out = (ctypes.c_double * max(n * dim, 1))()
    inside = (ctypes.c_uint8 * max(n, 1))()
    nout = ctypes.c_int64()
    err = _lib.Error()
    st = core.sm_warp_points(w, direction, 1 if strict else 0, n, ptr, out, inside,
                             ctypes.byref(nout), ctypes.byref(err))
    if st:
        raise_(err, st)
    return out, inside, nout.value


def _read_mesh_or_surface(core, path, raise_):
    """('mesh', sm_mesh*) or ('surface', sm_surface*) of path, read as
    `shapematch warp --mesh` does: a volume mesh first, else a surface."""
    err, serr = _lib.Error(), _lib.Error()
    m = ctypes.POINTER(_lib.Mesh)()
    st = core.sm_mesh_read(os.fsencode(path), ctypes.byref(m), ctypes.byref(err))
    if not st:
        return "mesh", m
    if st == 1:  # SM_ERR_IO: no file
        raise_(err, st)
    s = ctypes.POINTER(_lib.Surface)()
    st2 = core.sm_surface_read(os.fsencode(path), ctypes.byref(s), ctypes.byref(serr))
    if st2:
        serr.msg = ("%s is neither a mesh (%s) nor a surface (%s)" % (
            os.fsdecode(path), err.msg.decode("utf-8", "replace"),
            serr.msg.decode("utf-8", "replace"))).encode()[:_lib.ERROR_MSG_LEN - 1]
        raise_(serr, st2)
    return "surface", s


def _write_warped(core, kind, obj, out_coords, output, raise_):
    err = _lib.Error()
    path = os.fsencode(output)
    if kind == "surface":
        st = core.sm_surface_write(path, obj, out_coords, ctypes.byref(err))
    elif path.endswith(b".vtu"):
        st = core.sm_vtu_write(path, obj, out_coords, None, None, ctypes.byref(err))
    elif path.endswith((b".mesh", b".meshb", b".mesh.gz", b".meshb.gz")):
        st = core.sm_mesh_write_coords(path, obj, out_coords, ctypes.byref(err))
    else:
        raise ValueError("warp: %s: a volume mesh is written as .mesh, .meshb (optionally .gz) "
                         "or .vtu" % os.fsdecode(output))
    if st:
        raise_(err, st)


def _mesh(core, m, w, direction, strict, mesh, output, raise_):
    if isinstance(mesh, (str, bytes, os.PathLike)):
        kind, obj = _read_mesh_or_surface(core, mesh, raise_)
        try:
            c = obj.contents
            if c.dim != m.dim:
                raise ValueError("warp: %s is %dD and the map is %dD" % (
                    os.fsdecode(mesh), c.dim, m.dim))
            out, _, _ = _warp_points(core, w, direction, strict, c.coords, c.nverts, c.dim,
                                     raise_)
            if output is not None:
                _write_warped(core, kind, obj, out, output, raise_)
            return _arrays.out(out, ctypes.c_double, c.nverts, c.dim)
        finally:
            (core.sm_mesh_free if kind == "mesh" else core.sm_surface_free)(obj)
    if output is not None:
        raise ValueError("warp: output= is for a mesh given as a file (arrays come back)")
    verts = mesh[0] if isinstance(mesh, (tuple, list)) else mesh["vertices"]
    xyz, n, dim = _arrays.doubles(verts, "mesh vertices", cols=(2, 3))
    if dim != m.dim:
        raise ValueError("warp: the mesh is %dD and the map is %dD" % (dim, m.dim))
    out, _, _ = _warp_points(core, w, direction, strict, _doubles_ptr(xyz), n, dim, raise_)
    return _arrays.out(out, ctypes.c_double, n, dim)


def _field(core, m, w, direction, normalize, field, output, raise_):
    err = _lib.Error()
    sol = ctypes.POINTER(_lib.Sol)()
    try:
        if isinstance(field, (str, bytes, os.PathLike)):
            st = core.sm_sol_read(os.fsencode(field), ctypes.byref(sol), ctypes.byref(err))
            if st:
                raise_(err, st)
        else:
            a, rows, cols = _arrays.doubles(field, "field", cols=None)
            st = core.sm_sol_alloc(ctypes.byref(sol), m.dim, rows, cols or 1, ctypes.byref(err))
            if st:
                raise_(err, st)
            _arrays.copy_into(sol.contents.values, a)
        s = sol.contents
        if s.nverts != m.nverts or s.dim != m.dim:
            raise ValueError("warp: the field is %dD on %d vertices; the %s has %d in %dD" % (
                s.dim, s.nverts, "template" if direction == FORWARD else "result", m.nverts,
                m.dim))
        st = core.sm_warp_field(w, direction, s.ncomp, 1 if normalize else 0, s.values,
                                ctypes.byref(err))
        if not st and output is not None:
            st = core.sm_sol_write(os.fsencode(output), sol, ctypes.byref(err))
        if st:
            raise_(err, st)
        return _arrays.out(s.values, ctypes.c_double, s.nverts, s.ncomp if s.ncomp > 1 else 0)
    finally:
        if sol:
            core.sm_sol_free(sol)


def warp(result, raise_, points=None, mesh=None, field=None, inverse=False, strict=False,
         normalize=False, output=None):
    given = [x is not None for x in (points, mesh, field)]
    if sum(given) != 1:
        raise TypeError("warp: give exactly one of points=, mesh= and field=")
    if normalize and field is None:
        raise TypeError("warp: normalize= is for field=")
    if output is not None and points is not None:
        raise TypeError("warp: output= is for mesh= and field= (points come back as arrays)")
    core = _lib.core()
    direction = INVERSE if inverse else FORWARD
    mp = _Map(result, raise_)
    w = ctypes.c_void_p()
    try:
        err = _lib.Error()
        locate = 0 if field is not None else 1 << direction
        st = core.sm_warp_new(mp.mesh, mp.deformed, locate, ctypes.byref(w), ctypes.byref(err))
        if st:
            raise_(err, st)
        m = mp.mesh.contents
        if points is not None:
            xyz, n, dim = _arrays.doubles(points, "points", cols=(2, 3))
            if dim != m.dim:
                raise ValueError("warp: %dD points and the map is %dD" % (dim, m.dim))
            out, inside, _ = _warp_points(core, w, direction, strict, _doubles_ptr(xyz), n, dim,
                                          raise_)
            flags = (ctypes.c_int32 * max(n, 1))(*inside[:n])
            return (_arrays.out(out, ctypes.c_double, n, dim),
                    _arrays.out(flags, ctypes.c_int32, n, 0))
        if mesh is not None:
            return _mesh(core, m, w, direction, strict, mesh, output, raise_)
        return _field(core, m, w, direction, normalize, field, output, raise_)
    finally:
        if w.value:
            core.sm_warp_free(w)
        mp.close()
