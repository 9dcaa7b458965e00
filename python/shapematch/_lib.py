"""The two shared libraries through ctypes, with the C declarations of the
structs the package reads (core/include/shapematch/*.h and
proto/job/shapematch_job.h are their source; tests/python checks the
layouts against the C compiler's offsetof).

Where the libraries are looked up, first hit wins:
  1. $SHAPEMATCH_LIBDIR (a build tree: build/release);
  2. PREFIX/lib, this package being PREFIX/lib/python3/dist-packages/shapematch;
  3. the dynamic loader's search path (ldconfig, LD_LIBRARY_PATH).
"""
import ctypes
import os

SOVERSION = "0"
ERROR_MSG_LEN = 512
STATUS_NAMES = {0: "ok", 1: "io", 2: "format", 3: "invalid", 4: "nomem", 5: "numeric"}


class Error(ctypes.Structure):
    _fields_ = [("code", ctypes.c_int), ("msg", ctypes.c_char * ERROR_MSG_LEN)]


class DistanceSide(ctypes.Structure):
    """sm_distance_side (shapematch/sm_coverage.h)."""
    _fields_ = [("rms", ctypes.c_double), ("max", ctypes.c_double), ("mean", ctypes.c_double),
                ("p99", ctypes.c_double)]


class Distance(ctypes.Structure):
    """sm_distance (shapematch/sm_coverage.h)."""
    _fields_ = [("method", ctypes.c_int), ("result_to_target", DistanceSide),
                ("target_to_result", DistanceSide)]


class Progress(ctypes.Structure):
    """sm_progress (shapematch/sm_match.h)."""
    _fields_ = [("iteration", ctypes.c_int), ("J", ctypes.c_double), ("step", ctypes.c_double),
                ("boundary_l2", ctypes.c_double), ("boundary_max", ctypes.c_double),
                ("boundary_rms", ctypes.c_double), ("boundary_relative", ctypes.c_double),
                ("min_quality", ctypes.c_double), ("elapsed", ctypes.c_double),
                ("accepted", ctypes.c_int), ("rejected", ctypes.c_int),
                ("distance", Distance), ("energy", ctypes.c_double)]


def progress_row(p):
    """One history row (a dict) of an sm_progress: its numbers, and its
    distance by the names of the progress event (result_to_target: rms,
    max; target_to_result: rms, max, p99)."""
    row = {k: getattr(p, k) for k, _ in Progress._fields_ if k != "distance"}
    d = p.distance
    row["distance"] = {
        "result_to_target": {"rms": d.result_to_target.rms, "max": d.result_to_target.max},
        "target_to_result": {"rms": d.target_to_result.rms, "max": d.target_to_result.max,
                             "p99": d.target_to_result.p99}}
    return row


class Mesh(ctypes.Structure):
    """The leading members of sm_mesh (shapematch/sm_mesh.h): the ones a
    mesh made from arrays fills; the library allocates the whole struct."""
    _fields_ = [("dim", ctypes.c_int), ("nverts", ctypes.c_int32),
                ("coords", ctypes.POINTER(ctypes.c_double)),
                ("vert_refs", ctypes.POINTER(ctypes.c_int32)), ("nelems", ctypes.c_int32),
                ("elems", ctypes.POINTER(ctypes.c_int32)),
                ("elem_refs", ctypes.POINTER(ctypes.c_int32)), ("nfacets", ctypes.c_int32),
                ("facets", ctypes.POINTER(ctypes.c_int32)),
                ("facet_refs", ctypes.POINTER(ctypes.c_int32))]


class Sol(ctypes.Structure):
    """sm_sol (shapematch/sm_io.h)."""
    _fields_ = [("dim", ctypes.c_int), ("nverts", ctypes.c_int32), ("ncomp", ctypes.c_int),
                ("values", ctypes.POINTER(ctypes.c_double))]


class Surface(ctypes.Structure):
    """sm_surface (shapematch/sm_surface.h)."""
    _fields_ = [("dim", ctypes.c_int), ("nverts", ctypes.c_int32),
                ("coords", ctypes.POINTER(ctypes.c_double)), ("nfacets", ctypes.c_int32),
                ("facets", ctypes.POINTER(ctypes.c_int32)),
                ("facet_refs", ctypes.POINTER(ctypes.c_int32))]


class SurfaceHealth(ctypes.Structure):
    """sm_surface_health (shapematch/sm_surface.h)."""
    _fields_ = [(n, ctypes.c_int64) for n in (
        "open_edges", "nonmanifold_edges", "reoriented", "reoriented_within", "pieces_turned",
        "duplicates", "degenerate", "components", "open_components", "open_by_volume")] + \
        [("lo", ctypes.c_double * 3), ("hi", ctypes.c_double * 3)]


class RunMesh(ctypes.Structure):
    """sm_run_mesh (shapematch_job.h): a mesh as arrays the caller owns."""
    _fields_ = [("dim", ctypes.c_int), ("nverts", ctypes.c_int32),
                ("coords", ctypes.POINTER(ctypes.c_double)), ("nelems", ctypes.c_int32),
                ("elems", ctypes.POINTER(ctypes.c_int32)),
                ("elem_refs", ctypes.POINTER(ctypes.c_int32)),
                ("vert_refs", ctypes.POINTER(ctypes.c_int32)), ("nfacets", ctypes.c_int32),
                ("facets", ctypes.POINTER(ctypes.c_int32)),
                ("facet_refs", ctypes.POINTER(ctypes.c_int32))]


class RunSurface(ctypes.Structure):
    """sm_run_surface (shapematch_job.h): a target surface as arrays."""
    _fields_ = [("dim", ctypes.c_int), ("nverts", ctypes.c_int32),
                ("coords", ctypes.POINTER(ctypes.c_double)), ("nfacets", ctypes.c_int32),
                ("facets", ctypes.POINTER(ctypes.c_int32))]


class RunFiles(ctypes.Structure):
    """sm_run_files (shapematch_job.h), its members in the header's order
    (the image pair, then the inputs in memory were appended: the struct
    only grows at its end)."""
    _fields_ = [(n, ctypes.c_char_p) for n in (
        "template_mesh", "target_mesh", "target_sol", "target_surface", "template_name",
        "target_mesh_name", "target_sol_name", "target_surface_name", "target_image",
        "target_image_name")] + [
        ("template_arrays", ctypes.POINTER(RunMesh)),
        ("target_mesh_arrays", ctypes.POINTER(RunMesh)),
        ("target_sol_values", ctypes.POINTER(ctypes.c_double)),
        ("target_sol_count", ctypes.c_int32),
        ("target_surface_arrays", ctypes.POINTER(RunSurface)),
        ("template_surface", ctypes.c_char_p),
        ("template_surface_arrays", ctypes.POINTER(RunSurface)),
        ("template_image", ctypes.c_char_p),
        ("template_label", ctypes.c_int64)]


PROGRESS_FN = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.POINTER(Progress), ctypes.c_void_p)

_P = ctypes.POINTER
_c = ctypes


def _declare(lib, name, restype, *argtypes):
    f = getattr(lib, name)
    f.restype = restype
    f.argtypes = list(argtypes)


def _candidates(name):
    env = os.environ.get("SHAPEMATCH_LIBDIR")
    if env:
        yield os.path.join(env, name)
    here = os.path.dirname(os.path.abspath(__file__))
    # PREFIX/lib/python3/dist-packages/shapematch -> PREFIX/lib
    yield os.path.normpath(os.path.join(here, "..", "..", "..", name))
    yield name


def _open(name):
    last = None
    for path in _candidates(name):
        if os.sep in path and not os.path.exists(path):
            continue
        try:
            return ctypes.CDLL(path)
        except OSError as e:
            last = e
    raise OSError("shapematch: cannot load %s (set SHAPEMATCH_LIBDIR to the folder that "
                  "holds it): %s" % (name, last))


_core = None
_job = None


def core():
    """libshapematch.so: the core's public API."""
    global _core
    if _core is None:
        lib = _open("libshapematch.so." + SOVERSION)
        _declare(lib, "sm_mesh_alloc", _c.c_int, _P(_P(Mesh)), _c.c_int, _c.c_int32, _c.c_int32,
                 _c.c_int32, _P(Error))
        _declare(lib, "sm_mesh_free", None, _P(Mesh))
        _declare(lib, "sm_mesh_read", _c.c_int, _c.c_char_p, _P(_P(Mesh)), _P(Error))
        _declare(lib, "sm_mesh_write", _c.c_int, _c.c_char_p, _P(Mesh), _P(Error))
        _declare(lib, "sm_sol_alloc", _c.c_int, _P(_P(Sol)), _c.c_int, _c.c_int32, _c.c_int,
                 _P(Error))
        _declare(lib, "sm_sol_free", None, _P(Sol))
        _declare(lib, "sm_sol_read", _c.c_int, _c.c_char_p, _P(_P(Sol)), _P(Error))
        _declare(lib, "sm_sol_write", _c.c_int, _c.c_char_p, _P(Sol), _P(Error))
        _declare(lib, "sm_surface_alloc", _c.c_int, _P(_P(Surface)), _c.c_int, _c.c_int32,
                 _c.c_int32, _P(Error))
        _declare(lib, "sm_surface_read", _c.c_int, _c.c_char_p, _P(_P(Surface)), _P(Error))
        _declare(lib, "sm_surface_free", None, _P(Surface))
        _declare(lib, "sm_surface_repair", _c.c_int, _P(Surface), _P(SurfaceHealth), _P(Error))
        _declare(lib, "sm_sdf_new", _c.c_int, _P(Surface), _P(_c.c_void_p), _P(Error))
        _declare(lib, "sm_sdf_free", None, _c.c_void_p)
        _declare(lib, "sm_sdf_signed", _c.c_int, _c.c_void_p, _c.c_int64, _P(_c.c_double),
                 _P(_c.c_double), _P(Error))
        _core = lib
    return _core


def job():
    """libshapematch_job.so: a whole job in one call (sm_run_*)."""
    global _job
    if _job is None:
        core()  # the same copy of libshapematch.so for both
        lib = _open("libshapematch_job.so." + SOVERSION)
        _declare(lib, "sm_run_job", _c.c_int, _P(RunFiles), _c.c_char_p, PROGRESS_FN,
                 _c.c_void_p, _P(_c.c_int), _P(_c.c_void_p), _P(Error))
        _declare(lib, "sm_run_free", None, _c.c_void_p)
        _declare(lib, "sm_run_version", _c.c_char_p)
        for name in ("sm_run_outcome", "sm_run_message", "sm_run_summary"):
            _declare(lib, name, _c.c_char_p, _c.c_void_p)
        for name in ("sm_run_exit_code", "sm_run_dim"):
            _declare(lib, name, _c.c_int, _c.c_void_p)
        for name in ("sm_run_nverts", "sm_run_nelems"):
            _declare(lib, name, _c.c_int32, _c.c_void_p)
        for name in ("sm_run_coords", "sm_run_init_coords"):
            _declare(lib, name, _P(_c.c_double), _c.c_void_p)
        for name in ("sm_run_elems", "sm_run_elem_refs", "sm_run_vert_refs"):
            _declare(lib, name, _P(_c.c_int32), _c.c_void_p)
        _declare(lib, "sm_run_history", _P(Progress), _c.c_void_p, _P(_c.c_size_t))
        _declare(lib, "sm_run_write", _c.c_int, _c.c_void_p, _c.c_char_p, _c.c_char_p, _P(Error))
        _declare(lib, "sm_run_map_open", _c.c_int, _c.c_char_p, _P(_c.c_void_p), _P(Error))
        _declare(lib, "sm_run_map_new", _c.c_int, _c.c_int, _c.c_int32, _P(_c.c_double),
                 _P(_c.c_double), _c.c_int32, _P(_c.c_int32), _P(_c.c_void_p), _P(Error))
        _declare(lib, "sm_run_map_free", None, _c.c_void_p)
        _declare(lib, "sm_run_map_dim", _c.c_int, _c.c_void_p)
        _declare(lib, "sm_run_map_nverts", _c.c_int32, _c.c_void_p)
        _declare(lib, "sm_run_warp_points", _c.c_int, _c.c_void_p, _c.c_int, _c.c_int, _c.c_int,
                 _c.c_int, _c.c_int64, _P(_c.c_double), _P(_c.c_double), _P(_c.c_uint8),
                 _P(_c.c_int64), _P(_c.c_int64), _P(Error))
        _declare(lib, "sm_run_warp_field", _c.c_int, _c.c_void_p, _c.c_int, _c.c_int, _c.c_int,
                 _c.c_int32, _c.c_int, _P(_c.c_double), _P(Error))
        _declare(lib, "sm_run_warp_file", _c.c_int, _c.c_void_p, _c.c_int, _c.c_char_p,
                 _c.c_char_p, _c.c_int, _c.c_int, _c.c_int, _P(_P(_c.c_double)),
                 _P(_c.c_int64), _P(_c.c_int), _P(Error))
        _declare(lib, "sm_run_warp_values_free", None, _P(_c.c_double))
        _declare(lib, "sm_run_batch", _c.c_int, _c.c_char_p, _c.c_char_p, _c.c_size_t,
                 _c.c_char_p, _c.c_char_p, _c.c_int, _c.c_char_p, _P(Error))
        _declare(lib, "sm_run_batch_from", _c.c_int, _c.c_char_p, _c.c_char_p, _c.c_int,
                 _c.c_double, _c.c_char_p, _c.c_size_t, _c.c_char_p, _c.c_char_p, _c.c_int,
                 _c.c_char_p, _P(Error))
        _job = lib
    return _job
