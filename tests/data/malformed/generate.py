#!/usr/bin/env python3
"""Regenerates the malformed-input corpus read by tests/unit/test_malformed.c.

Each case is a folder <case>/ holding
  input.<ext>  the hostile file (.mesh .meshb .sol .solb, optionally .gz)
  error        a substring the reader's error message must contain
  status       (optional) the expected sm_status name, e.g. "format"

Run from anywhere: python3 tests/data/malformed/generate.py
Binary files are little-endian (the byte order of the machines we run on);
one case uses the swapped order on purpose.
"""
import gzip
import os
import re
import shutil
import struct
import sys

HERE = os.path.dirname(os.path.abspath(__file__))

# --------------------------------------------------------------------------
# ASCII helpers

SQUARE_VERTS = [(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
SQUARE_TRIS = [(1, 2, 3, 0), (1, 3, 4, 0)]
SQUARE_EDGES = [(1, 2, 1), (2, 3, 1), (3, 4, 1), (4, 1, 1)]


def ascii_mesh(head="MeshVersionFormatted 2\nDimension 2\n", verts=None, edges=None,
               tris=None, tail="End\n", nverts=None, ntris=None):
    verts = SQUARE_VERTS if verts is None else verts
    edges = SQUARE_EDGES if edges is None else edges
    tris = SQUARE_TRIS if tris is None else tris
    out = head
    out += "Vertices\n%s\n" % (len(verts) if nverts is None else nverts)
    # padded columns, as Gmsh writes them
    out += "".join(" ".join(str(x).rjust(12) for x in v) + "\n" for v in verts)
    if edges:
        out += "Edges\n%d\n" % len(edges)
        out += "".join(" ".join(str(x).rjust(6) for x in e) + "\n" for e in edges)
    out += "Triangles\n%s\n" % (len(tris) if ntris is None else ntris)
    out += "".join(" ".join(str(x).rjust(6) for x in t) + "\n" for t in tris)
    return (out + tail).encode()


def ascii_sol(dim=2, n=3, fields="1 1", values=None, head=None):
    values = ["0.5", "1.5", "-2"] if values is None else values
    out = head if head is not None else "MeshVersionFormatted 2\nDimension %d\n" % dim
    out += "SolAtVertices\n%d\n%s\n" % (n, fields)
    out += "".join(v + "\n" for v in values)
    return (out + "End\n").encode()


# --------------------------------------------------------------------------
# binary helpers (libMeshb layout)

class Meshb:
    def __init__(self, version=2, swap=False, code=1):
        self.version = version
        self.bo = ">" if swap else "<"
        self.pos_fmt = "q" if version >= 3 else "i"
        self.int_fmt = "q" if version == 4 else "i"
        self.real_fmt = "f" if version == 1 else "d"
        self.data = struct.pack(self.bo + "ii", code, version)

    def pack(self, fmt, *vals):
        return struct.pack(self.bo + fmt, *vals)

    def keyword(self, code, body, next_pos=None):
        """Appends a keyword; next_pos overrides the computed position."""
        header = 4 + struct.calcsize(self.pos_fmt)
        nxt = len(self.data) + header + len(body) if next_pos is None else next_pos
        self.data += self.pack("i", code) + self.pack(self.pos_fmt, nxt) + body

    def dimension(self, dim):
        self.keyword(3, self.pack("i", dim))

    def count(self, n):
        return self.pack(self.int_fmt, n)

    def vertices(self, verts, dim=2, n=None, next_pos=None):
        body = self.count(len(verts) if n is None else n)
        for v in verts:
            body += self.pack(self.real_fmt * dim, *v[:dim]) + self.pack(self.int_fmt, v[dim])
        self.keyword(4, body, next_pos)

    def elements(self, code, recs, n=None, next_pos=None):
        body = self.count(len(recs) if n is None else n)
        for r in recs:
            body += self.pack(self.int_fmt * len(r), *r)
        self.keyword(code, body, next_pos)

    def solution(self, values, ncomp, types=(1,), n=None, next_pos=None):
        body = self.count(len(values) // ncomp if n is None else n)
        body += self.pack("i", len(types)) + b"".join(self.pack("i", t) for t in types)
        body += b"".join(self.pack(self.real_fmt, v) for v in values)
        self.keyword(62, body, next_pos)

    def end(self):
        self.data += self.pack("i", 54) + self.pack(self.pos_fmt, 0)
        return self.data


def square_meshb(version=2, swap=False, tris=None, verts=None):
    b = Meshb(version, swap)
    b.dimension(2)
    b.vertices(SQUARE_VERTS if verts is None else verts)
    b.elements(5, SQUARE_EDGES)
    b.elements(6, SQUARE_TRIS if tris is None else tris)
    return b.end()


def scalar_solb(values=(0.5, 1.5, -2.0), types=(1,), dim=2, ncomp=1, n=None):
    b = Meshb(2)
    b.dimension(dim)
    b.solution(list(values), ncomp, types, n=n)
    return b.end()


# --------------------------------------------------------------------------
# the cases: name -> (file name, bytes, error substring, status or None)

CASES = {}


def case(name, filename, data, error, status="format"):
    assert name not in CASES, name
    CASES[name] = (filename, data, error, status)


# ASCII meshes
case("mesh-empty-file", "input.mesh", b"", "empty file")
case("mesh-only-comments", "input.mesh", b"# nothing here\n\n   # really\n", "missing Dimension")
full = ascii_mesh()
case("mesh-truncated-in-vertices", "input.mesh", full[:full.index(b"1            1            1")],
     "expected 2 coordinates and a reference in Vertices record 3 of 4")
case("mesh-truncated-in-triangles", "input.mesh", full[:full.rindex(b"     1      3      4")],
     "expected 3 vertex indices and a reference in Triangles record 2 of 2")
case("mesh-truncated-mid-record", "input.mesh", full[:full.rindex(b"4      0")],
     "Triangles record 2 of 2, found end of file")
case("mesh-more-records-than-count", "input.mesh", ascii_mesh(nverts=3),
     "where a keyword was expected")
case("mesh-fewer-records-than-count", "input.mesh", ascii_mesh(ntris=3),
     "Triangles record 3 of 3, found 'End'")
case("mesh-index-zero", "input.mesh", ascii_mesh(tris=[(1, 2, 3, 0), (0, 3, 4, 0)]),
     "vertex index 0 out of range [1, 4] in Triangles record 2 of 2")
case("mesh-index-above-nverts", "input.mesh", ascii_mesh(tris=[(1, 2, 5, 0), (1, 3, 4, 0)]),
     "vertex index 5 out of range [1, 4] in Triangles record 1 of 2")
case("mesh-index-negative", "input.mesh", ascii_mesh(tris=[(1, 2, 3, 0), (1, -3, 4, 0)]),
     "vertex index -3 out of range")
case("mesh-index-before-vertices", "input.mesh",
     b"MeshVersionFormatted 2\nDimension 2\nTriangles\n1\n1 2 9 0\n"
     b"Vertices\n3\n0 0 0\n1 0 0\n0 1 0\nEnd\n",
     "vertex index 9 out of range [1, 3] in Triangles record 1 of 1")
case("mesh-index-not-integer", "input.mesh", ascii_mesh(tris=[(1, 2, 3, 0), (1, "3.0", 4, 0)]),
     "expected 3 vertex indices and a reference in Triangles record 2 of 2, found '3.0'")
case("mesh-negative-count", "input.mesh", ascii_mesh(nverts=-4), "negative count -4 for Vertices")
case("mesh-huge-count-1e9", "input.mesh", ascii_mesh(nverts=10**9),
     "Vertices count 1000000000 exceeds the limit")
case("mesh-huge-count-int32-max", "input.mesh", ascii_mesh(ntris=2**31 - 1),
     "Triangles count 2147483647 exceeds the limit")
case("mesh-count-beyond-file-size", "input.mesh", ascii_mesh(nverts=150000000),
     "Vertices count 150000000 cannot fit")
case("mesh-count-not-a-number", "input.mesh", ascii_mesh(nverts="four"),
     "expected the number of Vertices, found 'four'")
case("mesh-count-overflow", "input.mesh", ascii_mesh(nverts="99999999999999999999999"),
     "is out of range")
case("mesh-nan-coordinate", "input.mesh",
     ascii_mesh(verts=[(0, 0, 1), (1, "nan", 1), (1, 1, 1), (0, 1, 1)]),
     "'nan' is not a finite number")
case("mesh-inf-coordinate", "input.mesh",
     ascii_mesh(verts=[(0, 0, 1), (1, 0, 1), ("-inf", 1, 1), (0, 1, 1)]),
     "'-inf' is not a finite number")
case("mesh-overflowing-coordinate", "input.mesh",
     ascii_mesh(verts=[(0, 0, 1), (1, 0, 1), (1, "1e999", 1), (0, 1, 1)]),
     "'1e999' is not a finite number")
case("mesh-trailing-garbage-after-number", "input.mesh",
     ascii_mesh(verts=[(0, 0, 1), ("1.0abc", 0, 1), (1, 1, 1), (0, 1, 1)]),
     "trailing characters after the number")
case("mesh-reference-out-of-range", "input.mesh",
     ascii_mesh(tris=[(1, 2, 3, 9999999999), (1, 3, 4, 0)]),
     "reference 9999999999 out of the 32-bit range")
case("mesh-unknown-keyword", "input.mesh",
     b"MeshVersionFormatted 2\nDimension 2\nVertexes\n4\n", "input.mesh:3: unknown keyword 'Vertexes'")
case("mesh-missing-dimension", "input.mesh", ascii_mesh(head="MeshVersionFormatted 2\n"),
     "Vertices before Dimension")
case("mesh-missing-vertices", "input.mesh",
     b"MeshVersionFormatted 2\nDimension 2\nEnd\n", "missing Vertices")
case("mesh-dimension-4", "input.mesh", ascii_mesh(head="MeshVersionFormatted 2\nDimension 4\n"),
     "Dimension 4 is not supported")
case("mesh-bad-version", "input.mesh", ascii_mesh(head="MeshVersionFormatted 7\nDimension 2\n"),
     "bad MeshVersionFormatted 7")
case("mesh-duplicate-dimension", "input.mesh",
     ascii_mesh(head="MeshVersionFormatted 2\nDimension 2\nDimension 2\n"), "duplicate Dimension")
case("mesh-duplicate-vertices", "input.mesh",
     ascii_mesh(head="MeshVersionFormatted 2\nDimension 2\nVertices\n1\n0 0 0\n"),
     "duplicate Vertices section")
case("mesh-quadrilaterals", "input.mesh",
     ascii_mesh(tris=[]).replace(b"Triangles\n0\n", b"Quadrilaterals\n1\n1 2 3 4 0\n"),
     "Quadrilaterals are not supported, shapematch needs simplices")
case("mesh-hexahedra", "input.mesh",
     b"MeshVersionFormatted 2\nDimension 3\nVertices\n1\n0 0 0 0\nHexahedra\n1\n"
     b"1 1 1 1 1 1 1 1 0\nEnd\n", "Hexahedra are not supported")
case("mesh-tetrahedra-in-2d", "input.mesh",
     ascii_mesh(tail="Tetrahedra\n1\n1 2 3 4 0\nEnd\n"), "Tetrahedra in a Dimension 2 mesh")
case("mesh-3d-surface-only", "input.mesh",
     ascii_mesh(head="MeshVersionFormatted 2\nDimension 3\n",
                verts=[(0, 0, 0, 1), (1, 0, 0, 1), (1, 1, 0.5, 1), (0, 1, 0, 1)]),
     "a surface mesh is not supported")
case("mesh-no-elements", "input.mesh", ascii_mesh(tris=[], edges=[]), "no elements")
case("mesh-sol-content", "input.mesh", ascii_sol(), "SolAtVertices in a mesh file")
case("mesh-token-too-long", "input.mesh",
     b"MeshVersionFormatted 2\nDimension 2\n" + b"V" * 500 + b"\n", "longer than")
case("mesh-unterminated-identifier", "input.mesh",
     b"MeshVersionFormatted 2\nIdentifier \"my mesh\nDimension 2\n", "unterminated string")
case("mesh-binary-garbage", "input.mesh",
     bytes((i * 151 + 7) % 256 for i in range(300)), "input.mesh:1:")

# gzip layers
case("gz-garbage-after-header", "input.mesh.gz",
     gzip.compress(full)[:10] + bytes((i * 37 + 11) % 256 for i in range(100)),
     "corrupt gzip data")
case("gz-truncated", "input.mesh.gz", gzip.compress(full * 1)[:-20],
     "truncated or corrupt gzip stream")
case("gz-huge-count", "input.mesh.gz", gzip.compress(ascii_mesh(nverts=100000000)),
     "Vertices count 100000000 cannot fit")
case("gz-truncated-meshb", "input.meshb.gz", gzip.compress(square_meshb())[:-12],
     "truncated or corrupt gzip stream")

# binary meshes
good = square_meshb()
case("meshb-truncated-in-vertices", "input.meshb", good[:40], "next keyword position 112 is past the end of the file")
b = Meshb(3)
b.dimension(2)
b.vertices(SQUARE_VERTS, next_pos=0)  # last keyword: no successor to check against
case("meshb-truncated-last-keyword", "input.meshb", b.data[:-7],
     "Vertices count 4 cannot fit")
case("meshb-truncated-in-header", "input.meshb", good[:6], "header: unexpected end of file")
cut = Meshb(2)
cut.dimension(2)
cut.vertices(SQUARE_VERTS)
case("meshb-no-end-keyword", "input.meshb", cut.data, "no End keyword")
case("meshb-bad-version", "input.meshb", struct.pack("<ii", 1, 5) + good[8:],
     "unsupported version 5")
case("meshb-garbage-after-header", "input.meshb",
     struct.pack("<ii", 1, 2) + bytes((i * 97 + 3) % 256 for i in range(64)),
     "points backwards")
b = Meshb(2)
b.dimension(2)
b.vertices(SQUARE_VERTS, next_pos=12)
case("meshb-next-position-backwards", "input.meshb", b.end(), "points backwards")
b = Meshb(2)
b.dimension(2)
b.keyword(40, b"\0" * 8, next_pos=10**6)
case("meshb-next-position-past-eof", "input.meshb", b.end(), "past the end of the file")
b = Meshb(2)
b.dimension(2)
b.vertices(SQUARE_VERTS, next_pos=len(b.data) + 8 + 4 + 4 * 20 + 4)
b.elements(6, SQUARE_TRIS)
case("meshb-next-position-inside-block", "input.meshb", b.end(),
     "Vertices block ends here but the next keyword position says")
b = Meshb(2)
b.dimension(2)
b.vertices(SQUARE_VERTS, n=10**9)
case("meshb-huge-count-1e9", "input.meshb", b.end(), "Vertices count 1000000000 exceeds the limit")
b = Meshb(2)
b.dimension(2)
b.vertices(SQUARE_VERTS)
b.elements(6, SQUARE_TRIS, n=2**31 - 1)
case("meshb-huge-count-int32-max", "input.meshb", b.end(), "exceeds the limit")
b = Meshb(2)
b.dimension(2)
b.vertices(SQUARE_VERTS, n=100000000)
case("meshb-count-beyond-file-size", "input.meshb", b.end(), "cannot fit")
b = Meshb(2)
b.dimension(2)
b.vertices(SQUARE_VERTS, n=-1)
case("meshb-negative-count", "input.meshb", b.end(), "negative count -1 for Vertices")
case("meshb-index-zero", "input.meshb", square_meshb(tris=[(1, 2, 3, 0), (0, 3, 4, 0)]),
     "Triangles record 2 of 2: vertex index 0 out of range [1, 4]")
case("meshb-index-above-nverts-swapped", "input.meshb",
     square_meshb(swap=True, tris=[(1, 2, 3, 0), (1, 3, 77, 0)]),
     "vertex index 77 out of range [1, 4]")
case("meshb-nan-coordinate", "input.meshb",
     square_meshb(verts=[(0, 0, 1), (1, float("nan"), 1), (1, 1, 1), (0, 1, 1)]),
     "coordinate 2 is not a finite number")
case("meshb-v1-inf-coordinate", "input.meshb",
     square_meshb(version=1, verts=[(0, 0, 1), (1, 0, 1), (float("inf"), 1, 1), (0, 1, 1)]),
     "not a finite number")
b = Meshb(2)
b.dimension(4)
case("meshb-dimension-4", "input.meshb", b.end(), "Dimension 4 is not supported")
b = Meshb(2)
b.vertices(SQUARE_VERTS)
case("meshb-missing-dimension", "input.meshb", b.end(), "Vertices before Dimension")
b = Meshb(2)
b.dimension(2)
b.vertices(SQUARE_VERTS)
b.elements(7, [(1, 2, 3, 4, 0)])
case("meshb-quadrilaterals", "input.meshb", b.end(),
     "Quadrilaterals are not supported, shapematch needs simplices")
b = Meshb(4)
b.dimension(2)
b.vertices(SQUARE_VERTS)
b.elements(6, [(1, 2, 3, 2**40)])
case("meshb-v4-reference-out-of-range", "input.meshb", b.end(), "out of the 32-bit range")

# ASCII solutions
case("sol-empty-file", "input.sol", b"", "empty file")
case("sol-two-fields", "input.sol", ascii_sol(fields="2 1 1"),
     "SolAtVertices has 2 fields; exactly one field is supported")
# a 2D symmetric tensor has 3 components (xx, xy, yy): 3 values are one record
case("sol-tensor-short", "input.sol", ascii_sol(fields="1 3"),
     "SolAtVertices count 3 cannot fit in the at most 16 bytes left")
case("sol-tensor-nan", "input.sol",
     ascii_sol(dim=3, n=1, fields="1 3", values=["1 0 1 0 nan 1"]),
     "'nan' is not a finite number")
case("sol-type-unknown", "input.sol", ascii_sol(fields="1 9"), "solution type 9 (unknown type)")
case("sol-size-mismatch-vs-dimension", "input.sol",
     ascii_sol(dim=3, n=3, fields="1 2", values=["1 2", "3 4", "5 6"]),
     "expected 3 values in SolAtVertices record 3 of 3, found 'End'")
case("sol-more-values-than-count", "input.sol", ascii_sol(n=2),
     "where a keyword was expected")
case("sol-nan-value", "input.sol", ascii_sol(values=["0.5", "NaN", "1"]),
     "'NaN' is not a finite number")
case("sol-missing-dimension", "input.sol", ascii_sol(head="MeshVersionFormatted 2\n"),
     "SolAtVertices before Dimension")
case("sol-dimension-4", "input.sol", ascii_sol(dim=4), "Dimension 4 is not supported")
case("sol-missing-solution", "input.sol", b"MeshVersionFormatted 2\nDimension 2\nEnd\n",
     "missing SolAtVertices")
case("sol-huge-count", "input.sol", ascii_sol(n=2**31 - 1), "exceeds the limit")
case("sol-mesh-keyword", "input.sol", ascii_mesh(), "unexpected keyword 'Vertices'")
case("sol-truncated-gz", "input.sol.gz", gzip.compress(ascii_sol())[:-10],
     "truncated or corrupt gzip stream")

# binary solutions
case("solb-two-fields", "input.solb", scalar_solb(types=(1, 1)),
     "SolAtVertices has 2 fields; exactly one field is supported")
case("solb-type-4", "input.solb", scalar_solb(types=(4,)), "solution type 4 (matrix)")
# a 3D symmetric tensor is 6 reals: one record's worth under a count of 2
case("solb-tensor-count-too-large", "input.solb",
     scalar_solb(values=[1, 0, 1, 0, 0, 1], types=(3,), dim=3, ncomp=6, n=2),
     "SolAtVertices count 2 cannot fit in the at most 56 bytes left")
case("solb-size-mismatch-vs-dimension", "input.solb",
     # 2D vectors (4 records) under a Dimension 3 header claiming 2 records
     scalar_solb(values=[1, 2, 3, 4, 5, 6, 7, 8], types=(2,), dim=3, ncomp=2, n=2),
     "next keyword position says")
case("solb-truncated", "input.solb", scalar_solb()[:-20], "past the end of the file")
case("solb-huge-count", "input.solb", scalar_solb()[:28] + struct.pack("<i", 10**9)
     + scalar_solb()[32:], "exceeds the limit")
case("solb-inf-value", "input.solb", scalar_solb(values=(1.0, float("-inf"), 2.0)),
     "value is not a finite number")


# --------------------------------------------------------------------------
# Gmsh .msh: a unit square of two triangles on surface 1 (physical 5)

MSH_NODES = [(1, 0.0, 0.0), (2, 1.0, 0.0), (3, 1.0, 1.0), (4, 0.0, 1.0)]
MSH_TRIS = [(1, 1, 2, 3), (2, 1, 3, 4)]


def msh41_ascii(nodes=None, tris=None, nnodes=None, ntris=None, etype=2, extra="",
                coord=None, head="$MeshFormat\n4.1 0 8\n$EndMeshFormat\n"):
    nodes = MSH_NODES if nodes is None else nodes
    tris = MSH_TRIS if tris is None else tris
    out = head + extra
    out += "$Entities\n0 0 1 0\n1 0 0 0 1 1 0 1 5 0\n$EndEntities\n"
    n = len(nodes) if nnodes is None else nnodes
    out += "$Nodes\n1 %s 1 %d\n2 1 0 %s\n" % (n, len(nodes), n)
    out += "".join("%d\n" % t for t, _, _ in nodes)
    out += "".join("%s %s 0\n" % (x if coord is None or t != 3 else coord, y)
                   for t, x, y in nodes)
    out += "$EndNodes\n"
    m = len(tris) if ntris is None else ntris
    out += "$Elements\n1 %s 1 %d\n2 1 %d %s\n" % (m, len(tris), etype, m)
    out += "".join(" ".join(str(v) for v in t) + "\n" for t in tris)
    return (out + "$EndElements\n").encode()


def msh41_binary(nnodes=None, node_tag=None, truncate=None, size=8, one=1):
    b = b"$MeshFormat\n4.1 1 %d\n" % size + struct.pack("<i", one) + b"\n$EndMeshFormat\n"
    b += b"$Entities\n" + struct.pack("<4Q", 0, 0, 1, 0)
    b += struct.pack("<i6dQiQ", 1, 0, 0, 0, 1, 1, 0, 1, 5, 0) + b"\n$EndEntities\n"
    n = 4 if nnodes is None else nnodes
    b += b"$Nodes\n" + struct.pack("<4Q", 1, n, 1, 4) + struct.pack("<3iQ", 2, 1, 0, n)
    tags = [1, 2, 3, 4] if node_tag is None else [1, 2, 3, node_tag]
    b += struct.pack("<4Q", *tags)
    for _, x, y in MSH_NODES:
        b += struct.pack("<3d", x, y, 0.0)
    b += b"\n$EndNodes\n$Elements\n" + struct.pack("<4Q", 1, 2, 1, 2)
    b += struct.pack("<3iQ", 2, 1, 2, 2)
    for t in MSH_TRIS:
        b += struct.pack("<4Q", *t)
    b += b"\n$EndElements\n"
    return b if truncate is None else b[:truncate]


def msh22(nodes=None, elems=None, nnodes=None):
    nodes = MSH_NODES if nodes is None else nodes
    elems = ["1 2 2 5 1 1 2 3", "2 2 2 5 1 1 3 4"] if elems is None else elems
    out = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"
    out += "$Nodes\n%s\n" % (len(nodes) if nnodes is None else nnodes)
    out += "".join("%d %s %s 0\n" % n for n in nodes) + "$EndNodes\n"
    out += "$Elements\n%d\n" % len(elems) + "".join(e + "\n" for e in elems)
    return (out + "$EndElements\n").encode()


_full41 = msh41_ascii()
case("msh-truncated", "input.msh", _full41[:_full41.index(b"$Elements")], "no $Elements section")
case("msh-truncated-mid-block", "input.msh", _full41[:_full41.rindex(b"1 3 4")],
     "expected a node tag of an element, found end of file")
case("msh-node-count-beyond-file-size", "input.msh", msh41_ascii(nnodes=10**8),
     "$Nodes count 100000000 cannot fit")
case("msh-huge-count", "input.msh", msh41_ascii(ntris=10**12), "exceeds the limit")
case("msh-node-tag-unknown", "input.msh", msh41_ascii(tris=[(1, 1, 2, 3), (2, 1, 3, 9)]),
     "input.msh:24: node tag 9 is not in $Nodes")
case("msh-nan-coordinate", "input.msh", msh41_ascii(coord="nan"), "is not a finite number")
case("msh-quadrangles", "input.msh", msh41_ascii(etype=3, tris=[(1, 1, 2, 3, 4)], ntris=1),
     "element type 3 (4-node quadrangle) is not supported")
case("msh-second-order", "input.msh", msh41_ascii(etype=9), "element type 9 (6-node second-order")
case("msh-bad-version", "input.msh",
     msh41_ascii(head="$MeshFormat\n3.0 0 8\n$EndMeshFormat\n"), "unsupported .msh version '3.0'")
case("msh-unterminated-section", "input.msh",
     msh41_ascii(extra="$NodeData\n1\n\"d\"\n"), "section $NodeData has no $EndNodeData")
case("msh-block-exceeds-header", "input.msh",
     _full41.replace(b"2 1 0 4\n", b"2 1 0 5\n"), "node block of 5 nodes exceeds")
case("msh-binary-truncated", "input.msh", msh41_binary(truncate=-60),
     "unexpected end of file")
case("msh-binary-count-beyond-file-size", "input.msh", msh41_binary(nnodes=10**7),
     "cannot fit in the at most")
case("msh-binary-unknown-node-tag", "input.msh", msh41_binary(node_tag=7),
     "node tag 4 is not in $Nodes")
case("msh-binary-data-size-4", "input.msh", msh41_binary(size=4), "data size 4 is not supported")
case("msh-binary-bad-endianness", "input.msh", msh41_binary(one=7),
     "endianness word is 7")
case("msh-binary-node-byte-offset", "input.msh", msh41_binary(nnodes=2**62),
     "input.msh: byte ")
case("msh22-bad-index", "input.msh", msh22(elems=["1 2 2 5 1 1 2 3", "2 2 2 5 1 1 3 0"]),
     "node tag 0 is not in $Nodes")
case("msh22-too-many-tags", "input.msh", msh22(elems=["1 2 1000 5 1 1 2 3"]),
     "1000 element tags is not in [0, 64]")
case("msh22-hexahedra", "input.msh", msh22(elems=["1 5 2 5 1 1 2 3 4 1 2 3 4"]),
     "element type 5 (8-node hexahedron)")
case("msh22-binary", "input.msh", b"$MeshFormat\n2.2 1 8\n", "binary .msh 2.2 is not supported")
case("msh-gz-truncated", "input.msh.gz", gzip.compress(_full41, mtime=0)[:-30],
     "gzip")
case("msh-surface-only", "input.msh", _full41.replace(b"1.0 1.0 0\n", b"1.0 1.0 0.5\n"),
     "surface mesh is not a volume mesh")
case("mesh-unknown-format", "input.mesh", b"solid x\nfacet normal 0 0 1\n",
     "a surface (STL), not a volume mesh (meshes are read as Medit")


# --------------------------------------------------------------------------
# target surfaces (cases named surface-*: read by sm_surface_read)

TET_V = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
TET_F = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]


def stl_binary(n=None, header=b"solid tetrahedron", extra=b"", coord=None, cut=None):
    b = header.ljust(80, b" ") + struct.pack("<I", len(TET_F) if n is None else n)
    for k, f in enumerate(TET_F):
        b += struct.pack("<3f", 0, 0, 0)
        for j, v in enumerate(f):
            p = TET_V[v]
            if coord is not None and k == 1 and j == 2:
                p = (coord, p[1], p[2])
            b += struct.pack("<3f", *p)
        b += b"\0\0"
    b += extra
    return b if cut is None else b[:cut]


def stl_ascii(facets=None, tail="endsolid t\n"):
    out = "solid t\n"
    for f in (TET_F if facets is None else facets):
        out += "facet normal 0 0 0\n outer loop\n"
        out += "".join("  vertex %s %s %s\n" % TET_V[v] for v in f)
        out += " endloop\nendfacet\n"
    return (out + tail).encode()


def obj(faces=("f 1 3 2", "f 1 2 4", "f 1 4 3", "f 2 3 4"), verts=None):
    verts = ["v %s %s %s" % v for v in TET_V] if verts is None else verts
    return ("\n".join(list(verts) + list(faces)) + "\n").encode()


case("surface-stl-binary-count-past-size", "input.stl", stl_binary(n=10**6),
     "binary STL facet count 1000000 does not fit")
case("surface-stl-binary-truncated", "input.stl", stl_binary(cut=84 + 50 * 3 + 20),
     "does not fit")
case("surface-stl-binary-trailing-bytes", "input.stl", stl_binary(n=3, header=b"binary"),
     "bytes after its 3 facets")
case("surface-stl-binary-nan", "input.stl", stl_binary(coord=float("nan"), header=b"nan"),
     "coordinate is not a finite number")
case("surface-stl-binary-zero-facets", "input.stl", stl_binary(n=0, header=b"x")[:84],
     "binary STL with 0 facets")
case("surface-stl-ascii-truncated", "input.stl", stl_ascii()[:-40], "input.stl:")
case("surface-stl-ascii-missing-endsolid", "input.stl", stl_ascii(tail=""),
     "missing 'endsolid'")
case("surface-stl-ascii-bad-keyword", "input.stl",
     stl_ascii().replace(b"outer loop", b"outer lop", 1), "expected 'loop', found 'lop'")
case("surface-stl-ascii-nan", "input.stl", stl_ascii().replace(b"vertex 1 0 0", b"vertex nan 0 0", 1),
     "is not a finite number")
case("surface-stl-gz-truncated", "input.stl.gz", gzip.compress(stl_ascii(), mtime=0)[:-12],
     "gzip")
case("surface-obj-index-zero", "input.obj", obj(faces=["f 0 1 2"]), "vertex index 0 out of range")
case("surface-obj-index-past-end", "input.obj", obj(faces=["f 1 2 5"]),
     "input.obj:5: vertex index 5 out of range")
case("surface-obj-negative-past-start", "input.obj", obj(faces=["f -1 -2 -5"]),
     "vertex index -5 out of range")
case("surface-obj-nan", "input.obj", obj(verts=["v 0 0 nan", "v 1 0 0", "v 0 1 0"],
                                         faces=["f 1 2 3"]), "3 finite coordinates")
case("surface-obj-two-vertex-face", "input.obj", obj(faces=["f 1 2"]), "at least 3 vertices")
case("surface-obj-bad-reference", "input.obj", obj(faces=["f 1 2x 3"]), "bad vertex reference")
case("surface-obj-no-faces", "input.obj", obj(faces=[]), "OBJ without faces")
case("surface-obj-unknown-statement", "input.obj", obj(faces=["f 1 2 3", "bogus 1"]),
     "unknown OBJ statement 'bogus'")
case("surface-obj-huge-line", "input.obj", b"v " + b"1" * 70000 + b"\n", "line longer than")
case("surface-unknown-format", "input.dat", b"\x00\x01garbage", "unknown surface format")
case("surface-msh-no-surface", "input.msh", _full41.replace(b"2 1 2 2", b"2 1 15 2")
     .replace(b"1 1 2 3\n2 1 3 4", b"1 1\n2 3"), "no surface")
case("surface-mesh-no-surface", "input.mesh",
     b"MeshVersionFormatted 2\nDimension 3\nVertices\n1\n0 0 0 0\nEnd\n", "no surface")


# PLY, OFF, VTK legacy and XML: edits of the samples of tests/data/formats/cells/
# (written by its generate.py)
def sample(name):
    with open(os.path.join(HERE, "..", "formats", "cells", name), "rb") as f:
        return f.read()


_ply = sample("surface-ascii.ply")
_ple = sample("surface-le.ply")
_off = sample("surface.off")
_vtk = sample("volume-42-ascii.vtk")
_vtu = sample("volume-ascii.vtu")
_vtz = sample("volume-binary-zlib.vtu")
_vta = sample("volume-appended-raw.vtu")
case("surface-ply-no-end-header", "input.ply", _ply.split(b"end_header")[0], "without end_header")
case("surface-ply-count-past-size", "input.ply", _ply.replace(b"vertex 8", b"vertex 100000000"),
     "does not fit")
case("surface-ply-index-out-of-range", "input.ply", _ply.replace(b"4 0 2 3 1", b"4 0 2 3 99"),
     "out of range")
case("surface-ply-bad-format", "input.ply", _ply.replace(b"format ascii", b"format binary_pdp"),
     "unknown format line")
case("surface-ply-truncated", "input.ply", _ple[:-30], "PLY")
case("surface-ply-nan", "input.ply", _ply.replace(b"0.3333333432674408 ", b"nan ", 1), "PLY")
case("surface-ply-long-list", "input.ply", _ply.replace(b"4 0 2 3 1", b"100000 0 2 3 1"),
     "list length")
case("surface-ply-no-xyz", "input.ply", _ply.replace(b"property float z", b"property float w"),
     "no x, y and z")
case("surface-ply-faces-first", "input.ply",
     b"ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\n"
     b"element vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
     b"3 0 1 2\n0 0 0\n1 0 0\n0 1 0\n", "faces before the vertex element")
case("surface-off-count-past-size", "input.off", _off.replace(b"8 6 0", b"8 60000000 0"),
     "does not fit")
case("surface-off-two-vertex-face", "input.off", _off.replace(b"4 0 2 3 1", b"2 0 2"),
     "at least 3")
case("surface-off-negative-index", "input.off", _off.replace(b"4 0 2 3 1", b"4 0 2 3 -1"),
     "out of range")
case("surface-vtk-bad-dataset", "input.vtk", _vtk.replace(b"UNSTRUCTURED_GRID", b"STRUCTURED_POINTS"),
     "is not read")
case("surface-vtk-hexahedron", "input.vtk", _vtk.replace(b"CELL_TYPES 18\n10", b"CELL_TYPES 18\n12"),
     "hexahedron")
case("surface-vtk-cells-past-end", "input.vtk", _vtk.replace(b"CELLS 18 78", b"CELLS 19 78"),
     "runs past")
case("surface-vtk-points-past-size", "input.vtk", _vtk.replace(b"POINTS 8 ", b"POINTS 100000000 "),
     "do not fit")
case("mesh-vtk-index-out-of-range", "input.vtk", _vtk.replace(b"4 0 1 3 7", b"4 0 1 3 8"),
     "out of range")
case("mesh-vtk-truncated", "input.vtk", _vtk[:len(_vtk) // 2], "input.vtk")
case("mesh-vtu-no-tetrahedra", "input.vtu",
     _vtu.replace(b">\n10 10 10 10 10 10 ", b">\n5 5 5 5 5 5 "), "type")
case("surface-vtu-compressor", "input.vtu",
     _vtz.replace(b"vtkZLibDataCompressor", b"vtkLZ4DataCompressor"), "compressor")
_z = _vtz.split(b'Name="Points"')
_zl = _z[1].split(b"\n")
case("surface-vtu-zlib-corrupt", "input.vtu",
     _z[0] + b'Name="Points"' + b"\n".join([_zl[0], _zl[1][:12] + b"AAAAAAAA" + _zl[1][20:]]
                                           + _zl[2:]), "Points")
case("surface-vtu-appended-offset", "input.vtu",
     re.sub(rb'(Name="Points" NumberOfComponents="3" format="appended" offset=")[0-9]+',
            rb"\g<1>999999", _vta), "Points: no appended data")
case("surface-vtu-appended-short", "input.vtu", _vta[:-300], "no appended data")
case("surface-vtu-appended-cut", "input.vtu", _vta[:-120], "needed")
case("surface-vtu-two-pieces", "input.vtu", _vtu.replace(b"</Piece>", b"</Piece><Piece NumberOfPoints=\"0\"/>"),
     "more than one Piece")


# 3 MiB of coordinates from 5 KB: refused before the points are allocated
sys.path.insert(0, os.path.join(HERE, "..", "..", "lib"))
from zlib_bomb import zlib_bomb_vtu  # noqa: E402
case("mesh-vtu-zlib-bomb", "input.vtu", zlib_bomb_vtu(1 << 18), "more than 64 times the file",
     "nomem")
case("surface-vtu-text-short", "input.vtu", _vtu.replace(b"NumberOfPoints=\"8\"", b"NumberOfPoints=\"9\""),
     "Points")
case("surface-vtu-no-points", "input.vtu",
     b'<VTKFile type="UnstructuredGrid"><UnstructuredGrid><Piece NumberOfPoints="0" '
     b'NumberOfCells="1"><Cells><DataArray type="Int32" Name="connectivity" format="ascii">'
     b'0 1 2</DataArray><DataArray type="Int32" Name="offsets" format="ascii">3</DataArray>'
     b'<DataArray type="UInt8" Name="types" format="ascii">5</DataArray></Cells></Piece>'
     b'</UnstructuredGrid></VTKFile>', "out of range")
case("surface-text-unknown", "input.txt", b"hello, this is not a surface\n" * 10,
     "unknown surface format")


def main():
    for name in os.listdir(HERE):
        path = os.path.join(HERE, name)
        # image-* cases are generate_image.py's
        if os.path.isdir(path) and name not in CASES and not name.startswith("image-"):
            shutil.rmtree(path)
    for name, (filename, data, error, status) in sorted(CASES.items()):
        d = os.path.join(HERE, name)
        if os.path.isdir(d):
            shutil.rmtree(d)
        os.makedirs(d)
        with open(os.path.join(d, filename), "wb") as f:
            f.write(data)
        with open(os.path.join(d, "error"), "w") as f:
            f.write(error + "\n")
        if status:
            with open(os.path.join(d, "status"), "w") as f:
                f.write(status + "\n")
    print("%d cases" % len(CASES))


if __name__ == "__main__":
    main()
