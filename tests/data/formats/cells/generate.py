#!/usr/bin/env python3
"""Writes the PLY, OFF and VTK samples read by tests/unit/test_cell_formats.c,
each beside the Medit file of the same content (ref-*.mesh), written
independently here: the C test reads both and compares them exactly.

Two shapes: the surface of a box (six quadrilaterals, fan-triangulated by
the readers from their first corner, as ref-surface.mesh lists them) and a
box cut into six tetrahedra (Kuhn), each with reference 1..6, with its
twelve boundary triangles, references 11..16 by side.  Coordinates are
float32 values (exact in every encoding).  Standard library only.

Run: python3 tests/data/formats/cells/generate.py
"""
import base64
import os
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))


def f32(x):
    return struct.unpack("<f", struct.pack("<f", x))[0]


LO, H = f32(1.0 / 3.0), f32(0.1)
PTS = [(f32(LO + H * (i & 1)), f32(LO + H * (i >> 1 & 1)), f32(LO + H * (i >> 2 & 1)))
       for i in range(8)]
# the box's sides as quadrilaterals, outward, with their references
QUADS = [((0, 2, 3, 1), 11), ((4, 5, 7, 6), 12), ((0, 1, 5, 4), 13),
         ((2, 6, 7, 3), 14), ((0, 4, 6, 2), 15), ((1, 3, 7, 5), 16)]
TRIS = [((q[0], q[k], q[k + 1]), r) for q, r in QUADS for k in (1, 2)]
# Kuhn's six tetrahedra along the diagonal 0-7
TETS = [((0, 1, 3, 7), 1), ((0, 1, 7, 5), 2), ((0, 4, 5, 7), 3),
        ((0, 2, 7, 3), 4), ((0, 6, 7, 2), 5), ((0, 4, 7, 6), 6)]


def write(name, data):
    with open(os.path.join(HERE, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


def medit(tris, tets):
    out = "MeshVersionFormatted 2\nDimension 3\nVertices\n%d\n" % len(PTS)
    out += "".join("%r %r %r 0\n" % p for p in PTS)
    out += "Triangles\n%d\n" % len(tris)
    out += "".join("%d %d %d %d\n" % (t[0] + 1, t[1] + 1, t[2] + 1, r) for t, r in tris)
    if tets:
        out += "Tetrahedra\n%d\n" % len(tets)
        out += "".join("%d %d %d %d %d\n" % (tuple(v + 1 for v in t) + (r,)) for t, r in tets)
    return out + "End\n"


# ---- PLY ----

def ply(fmt):
    head = ("ply\nformat %s 1.0\ncomment made by generate.py\nelement vertex %d\n"
            "property float x\nproperty float y\nproperty float z\nproperty uchar red\n"
            "element face %d\nproperty list uchar int vertex_indices\n"
            "property list uchar float texcoord\nelement edge 1\nproperty int vertex1\n"
            "property int vertex2\nend_header\n" % (fmt, len(PTS), len(QUADS)))
    if fmt == "ascii":
        body = "".join("%r %r %r 200\n" % p for p in PTS)
        body += "".join("4 %d %d %d %d 2 0.5 0.25\n" % q for q, _ in QUADS)
        body += "0 1\n"
        return head.encode() + body.encode()
    e = "<" if fmt == "binary_little_endian" else ">"
    body = b"".join(struct.pack(e + "fffB", *p, 200) for p in PTS)
    body += b"".join(struct.pack(e + "B4iB2f", 4, *q, 2, 0.5, 0.25) for q, _ in QUADS)
    body += struct.pack(e + "2i", 0, 1)
    return head.encode() + body


def off(kind):
    out = "%s\n# a comment\n%d %d 0\n" % (kind, len(PTS), len(QUADS))
    extra = " 0.5 0.5 0.5 1" if kind == "COFF" else ""
    out += "".join("%r %r %r%s\n" % (p + (extra,)) for p in PTS)
    out += "".join("4 %d %d %d %d 255 0 0\n" % q for q, _ in QUADS)
    return out


# ---- VTK legacy ----

def legacy(version, binary, poly):
    out = ["# vtk DataFile Version %s\nmade by generate.py\n%s\nDATASET %s\n"
           % (version, "BINARY" if binary else "ASCII",
              "POLYDATA" if poly else "UNSTRUCTURED_GRID")]
    cells = [(q, r, 9) for q, r in QUADS] if poly else \
        [(t, r, 10) for t, r in TETS] + [(t, r, 5) for t, r in TRIS]

    def arr(vals, fmt):
        if binary:
            return struct.pack(">%d%s" % (len(vals), fmt), *vals) + b"\n"
        return (" ".join(repr(v) if fmt in "fd" else str(v) for v in vals) + "\n").encode()
    out = [out[0].encode(), ("POINTS %d float\n" % len(PTS)).encode(),
           arr([x for p in PTS for x in p], "f")]
    kw = "POLYGONS" if poly else "CELLS"
    nconn = sum(len(c[0]) for c in cells)
    if version.startswith("5"):
        offs = [0]
        for c in cells:
            offs.append(offs[-1] + len(c[0]))
        out += [("%s %d %d\nOFFSETS vtktypeint64\n" % (kw, len(offs), nconn)).encode(),
                arr(offs, "q"), b"CONNECTIVITY vtktypeint64\n",
                arr([v for c in cells for v in c[0]], "q")]
    else:
        out += [("%s %d %d\n" % (kw, len(cells), nconn + len(cells))).encode(),
                arr([x for c in cells for x in (len(c[0]),) + tuple(c[0])], "i")]
    if not poly:
        out += [("CELL_TYPES %d\n" % len(cells)).encode(), arr([c[2] for c in cells], "i")]
    out += [("POINT_DATA %d\nSCALARS d double 1\nLOOKUP_TABLE default\n" % len(PTS)).encode(),
            arr([0.5] * len(PTS), "d")]
    out += [("CELL_DATA %d\nSCALARS other int 1\nLOOKUP_TABLE default\n" % len(cells)).encode(),
            arr([7] * len(cells), "i"),
            b"FIELD FieldData 2\nquality 1 %d float\n" % len(cells), arr([1.0] * len(cells), "f"),
            b"CellEntityIds 1 %d int\n" % len(cells), arr([c[1] for c in cells], "i")]
    return b"".join(out)


# ---- VTK XML ----

class Xml:
    """One .vtu/.vtp writer in a given encoding: fmt ascii, binary or
    appended; raw or base64 appended; zlib or not; header UInt32/UInt64;
    byte order."""

    def __init__(self, fmt, raw=False, zlib_=False, header="UInt32", big=False):
        self.fmt, self.raw, self.zlib, self.header, self.big = fmt, raw, zlib_, header, big
        self.appended = b""

    def block(self, data):
        e = ">" if self.big else "<"
        h = e + ("Q" if self.header == "UInt64" else "I")
        if not self.zlib:
            return struct.pack(h, len(data)), data
        bs = 64  # small blocks: several of them, a partial last one
        blocks = [zlib.compress(data[i:i + bs]) for i in range(0, len(data), bs)] or []
        last = len(data) % bs
        head = struct.pack(e + ("Q" if self.header == "UInt64" else "I") * (3 + len(blocks)),
                           len(blocks), bs, last, *[len(b) for b in blocks])
        return head, b"".join(blocks)

    def array(self, name, vtype, fmt, vals, ncomp=1):
        attrs = 'type="%s" Name="%s" NumberOfComponents="%d"' % (vtype, name, ncomp)
        if self.fmt == "ascii":
            text = " ".join(repr(v) if fmt in "fd" else str(v) for v in vals)
            return '<DataArray %s format="ascii">\n%s\n</DataArray>\n' % (attrs, text)
        e = ">" if self.big else "<"
        head, data = self.block(struct.pack(e + "%d%s" % (len(vals), fmt), *vals))
        if self.fmt == "binary":
            enc = (base64.b64encode(head) + base64.b64encode(data) if self.zlib
                   else base64.b64encode(head + data)).decode()
            return '<DataArray %s format="binary">\n%s\n</DataArray>\n' % (attrs, enc)
        off = len(self.appended)
        if self.raw:
            self.appended += head + data
        elif self.zlib:
            self.appended += base64.b64encode(head) + base64.b64encode(data)
        else:
            self.appended += base64.b64encode(head + data)
        return '<DataArray %s format="appended" offset="%d"/>\n' % (attrs, off)

    def file(self, poly):
        kind = "PolyData" if poly else "UnstructuredGrid"
        cells = [(q, r, 9) for q, r in QUADS] if poly else \
            [(t, r, 10) for t, r in TETS] + [(t, r, 5) for t, r in TRIS]
        offs, o = [], 0
        for c in cells:
            o += len(c[0])
            offs.append(o)
        conn = [v for c in cells for v in c[0]]
        body = '<CellData Scalars="ref">\n' + \
            self.array("quality", "Float32", "f", [1.0] * len(cells)) + \
            self.array("gmsh:physical", "Int32", "i", [c[1] for c in cells]) + "</CellData>\n"
        body += "<Points>\n" + self.array("Points", "Float32", "f",
                                          [x for p in PTS for x in p], 3) + "</Points>\n"
        tag = "Polys" if poly else "Cells"
        body += "<%s>\n" % tag + self.array("connectivity", "Int64", "q", conn) + \
            self.array("offsets", "Int64", "q", offs)
        if not poly:
            body += self.array("types", "UInt8", "B", [c[2] for c in cells])
        body += "</%s>\n" % tag
        counts = 'NumberOfPolys="%d"' % len(cells) if poly else 'NumberOfCells="%d"' % len(cells)
        attrs = 'type="%s" version="1.0" byte_order="%s" header_type="%s"' % (
            kind, "BigEndian" if self.big else "LittleEndian", self.header)
        if self.zlib:
            attrs += ' compressor="vtkZLibDataCompressor"'
        out = ('<?xml version="1.0"?>\n<!-- made by generate.py -->\n<VTKFile %s>\n<%s>\n'
               '<Piece NumberOfPoints="%d" %s>\n%s</Piece>\n</%s>\n'
               % (attrs, kind, len(PTS), counts, body, kind)).encode()
        if self.fmt == "appended":
            out += ('<AppendedData encoding="%s">\n_' % ("raw" if self.raw else "base64")
                    ).encode() + self.appended + b"\n</AppendedData>\n"
        return out + b"</VTKFile>\n"


def main():
    write("ref-surface.mesh", medit(TRIS, None))
    write("ref-volume.mesh", medit(TRIS, TETS))
    write("surface-ascii.ply", ply("ascii"))
    write("surface-le.ply", ply("binary_little_endian"))
    write("surface-be.ply", ply("binary_big_endian"))
    write("surface.off", off("OFF"))
    write("surface-colours.off", off("COFF"))
    for v, b in (("4.2", 0), ("4.2", 1), ("5.1", 0), ("5.1", 1)):
        suffix = "%s-%s" % (v.replace(".", ""), "binary" if b else "ascii")
        write("volume-%s.vtk" % suffix, legacy(v, b, False))
        write("surface-%s.vtk" % suffix, legacy(v, b, True))
    variants = {
        "ascii": Xml("ascii"),
        "binary": Xml("binary"),
        "binary-zlib": Xml("binary", zlib_=True),
        "binary-zlib-uint64-be": Xml("binary", zlib_=True, header="UInt64", big=True),
        "appended-raw": Xml("appended", raw=True),
        "appended-raw-zlib": Xml("appended", raw=True, zlib_=True),
        "appended-base64": Xml("appended"),
        "appended-base64-zlib-uint64": Xml("appended", zlib_=True, header="UInt64"),
    }
    for name, x in variants.items():
        write("volume-%s.vtu" % name, x.file(False))
    for name in ("ascii", "binary-zlib", "appended-raw-zlib"):
        write("surface-%s.vtp" % name, variants[name].__class__(
            variants[name].fmt, variants[name].raw, variants[name].zlib).file(True))


if __name__ == "__main__":
    main()
