"""Arrays in and out, with numpy when it is installed (Debian's
python3-numpy) and without it: inputs may be numpy arrays, objects with
the buffer protocol (array.array, memoryview) or nested sequences; outputs
are numpy arrays, or Matrix objects (a row a[i], an entry a[i, j],
a.tolist(), a.shape) when numpy is missing.

numpy is imported on first need, not with the package: its import costs
more than a whole 2D match's start-up (0.06 s idle, 0.3 s on a loaded
machine, bench/python.sh), and `match(...).write(dir)` needs no array.
`_arrays.numpy` still names the module (None without it)."""
import array
import ctypes
import sys

_numpy = False  # not looked up yet


def _np():
    """numpy, imported now if it was not (None when it is missing)."""
    global _numpy
    if _numpy is False:
        try:
            import numpy as module
        except ImportError:  # the package works without it
            module = None
        _numpy = module
    return _numpy


def __getattr__(name):
    if name == "numpy":
        return _np()
    raise AttributeError("module %r has no attribute %r" % (__name__, name))


def _flat(x, typecode, what):
    """(array.array of typecode, rows, cols) of a 1-D or 2-D input."""
    # plain lists and tuples do not need numpy (read below as they are);
    # anything else may be an array type only numpy understands
    numpy = sys.modules.get("numpy") if isinstance(x, (list, tuple)) else _np()
    if numpy is not None and not isinstance(x, (bytes, bytearray)):
        a = numpy.asarray(x)
        if a.ndim not in (1, 2):
            raise ValueError("%s: expected a 1-D or 2-D array (got %d dimensions)" % (what, a.ndim))
        if typecode == "d":
            a = numpy.ascontiguousarray(a, dtype=numpy.float64)
        else:
            if a.size and a.dtype.kind not in "iu":
                raise ValueError("%s: expected integers (got %s)" % (what, a.dtype))
            a = numpy.ascontiguousarray(a, dtype=numpy.int32)
        rows = a.shape[0]
        cols = a.shape[1] if a.ndim == 2 else 0
        out = array.array(typecode)
        out.frombytes(a.tobytes())
        return out, rows, cols
    if isinstance(x, Matrix):
        vals = x._m.tolist()
        return array.array(typecode, vals if typecode == "d" or x._m.format != "d" else
                           (_int(v, what) for v in vals)), x.shape[0], \
            (x.shape[1] if x.ndim == 2 else 0)
    try:
        m = memoryview(x)
    except TypeError:
        m = None
    if m is not None and m.ndim in (1, 2) and m.c_contiguous and \
            array.array(typecode).itemsize == m.itemsize and m.format in (typecode, "=" + typecode):
        out = array.array(typecode)
        out.frombytes(m.tobytes())
        return out, m.shape[0], (m.shape[1] if m.ndim == 2 else 0)
    rows = list(x)
    if rows and isinstance(rows[0], (list, tuple)) or (rows and hasattr(rows[0], "__len__")):
        cols = len(rows[0])
        out = array.array(typecode)
        for i, r in enumerate(rows):
            if len(r) != cols:
                raise ValueError("%s: row %d has %d entries, row 0 has %d" % (what, i, len(r), cols))
            out.extend(float(v) if typecode == "d" else _int(v, what) for v in r)
        return out, len(rows), cols
    return array.array(typecode, (float(v) if typecode == "d" else _int(v, what) for v in rows)), \
        len(rows), 0


def _int(v, what):
    if isinstance(v, float) and v != int(v):
        raise ValueError("%s: expected integers (got %r)" % (what, v))
    return int(v)


def doubles(x, what, cols=None):
    """x as contiguous doubles: (array.array('d'), rows, cols); cols 0 for
    a 1-D input.  cols: the number of columns required (None: any)."""
    a, rows, c = _flat(x, "d", what)
    if cols is not None and c not in cols:
        raise ValueError("%s: expected %s columns (got %s)" % (
            what, " or ".join(map(str, cols)), c if c else "a 1-D array"))
    return a, rows, c


def int32s(x, what, cols=None):
    a, rows, c = _flat(x, "i", what)
    if array.array("i").itemsize != 4:
        raise RuntimeError("C int is not 32 bits here")
    if cols is not None and c not in cols:
        raise ValueError("%s: expected %s columns (got %s)" % (
            what, " or ".join(map(str, cols)), c if c else "a 1-D array"))
    return a, rows, c


def copy_into(ptr, a):
    """Copies array.array a to the C array at ptr."""
    if len(a):
        addr, n = a.buffer_info()
        ctypes.memmove(ptr, addr, n * a.itemsize)


class Matrix:
    """A read-only rows x cols array of doubles or int32 (cols 0: 1-D)
    over a memoryview: what the package returns when numpy is missing."""

    def __init__(self, view, rows, cols):
        self._m = view
        self.shape = (rows, cols) if cols else (rows,)
        self.ndim = len(self.shape)

    def __len__(self):
        return self.shape[0]

    def __getitem__(self, key):
        if self.ndim == 1:
            return self._m[key]
        if isinstance(key, tuple):
            i, j = key
            return self._m[i * self.shape[1] + j]
        if isinstance(key, slice):
            return [self[i] for i in range(*key.indices(self.shape[0]))]
        if key < 0:
            key += self.shape[0]
        if not 0 <= key < self.shape[0]:
            raise IndexError("row index out of range")
        c = self.shape[1]
        return tuple(self._m[key * c:(key + 1) * c])

    def __iter__(self):
        return (self[i] for i in range(self.shape[0]))

    def tolist(self):
        if self.ndim == 1:
            return self._m.tolist()
        return [list(r) for r in self]

    def __eq__(self, other):
        return isinstance(other, Matrix) and self.shape == other.shape and \
            self._m.tobytes() == other._m.tobytes()

    def tobytes(self):
        return self._m.tobytes()

    def __repr__(self):
        return "Matrix(shape=%r)" % (self.shape,)

    def __buffer__(self, flags):  # Python >= 3.12: memoryview(a), numpy.asarray(a)
        return self._m


def raw(ptr, ctype, rows, cols):
    """A copy of the C array at ptr (rows x cols; cols 0: 1-D) as bytes,
    for wrap() to make an array of when it is wanted (no numpy yet)."""
    n = rows * (cols or 1)
    data = bytearray(n * ctypes.sizeof(ctype))
    if n:
        ctypes.memmove((ctypes.c_char * len(data)).from_buffer(data), ptr, len(data))
    return data, "d" if ctype is ctypes.c_double else "i", rows, cols


def out(ptr, ctype, rows, cols):
    """A copy of the C array at ptr (rows x cols; cols 0: 1-D), as a numpy
    array or a memoryview."""
    return wrap(raw(ptr, ctype, rows, cols))


def wrap(copy):
    """The array of a raw() copy (sharing its bytes)."""
    raw, fmt, rows, cols = copy
    numpy = _np()
    if numpy is not None:
        a = numpy.frombuffer(raw, dtype=numpy.float64 if fmt == "d" else numpy.int32)
        return a.reshape((rows, cols)) if cols else a
    return Matrix(memoryview(raw).cast(fmt), rows, cols)


def minus(a, b):
    """a - b elementwise, for two outputs of out()."""
    if _np() is not None:
        return a - b
    flat = array.array("d", (x - y for x, y in zip(a._m, b._m)))
    return Matrix(memoryview(flat), a.shape[0], a.shape[1] if a.ndim == 2 else 0)


def rows_of(a):
    """Nested lists of an output (for JSON, writing)."""
    return a.tolist()
