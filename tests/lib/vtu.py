"""A reader of the .vtu files shapematch writes, for the test suites, in
Python's standard library only (ElementTree, base64, zlib, struct): an
implementation independent of the core's reader (core/io/sm_io_vtkxml.c).
read(path) -> (piece attributes, {"Points": [...], "connectivity": [...],
"ref": [...], ...}) with every DataArray decoded to a flat list, whether
format="ascii" or format="binary" (base64, plain or compressed by
vtkZLibDataCompressor: a header [blocks, block size, last size, sizes...]
encoded on its own, then the blocks)."""
import base64
import struct
import xml.etree.ElementTree as ET
import zlib

TYPES = {"Int8": "b", "UInt8": "B", "Int16": "h", "UInt16": "H", "Int32": "i", "UInt32": "I",
         "Int64": "q", "UInt64": "Q", "Float32": "f", "Float64": "d"}


def _b64len(nbytes):
    return (nbytes + 2) // 3 * 4


def _binary(text, root, vtype):
    e = ">" if root.get("byte_order") == "BigEndian" else "<"
    h = "Q" if root.get("header_type") == "UInt64" else "I"
    hs = struct.calcsize(h)
    text = "".join(text.split())
    if root.get("compressor") == "vtkZLibDataCompressor":
        nb = struct.unpack(e + h, base64.b64decode(text[:_b64len(hs)])[:hs])[0]
        hlen = _b64len((3 + nb) * hs)
        head = struct.unpack(e + h * (3 + nb), base64.b64decode(text[:hlen]))
        blob = base64.b64decode(text[hlen:])
        out, at = b"", 0
        for size in head[3:]:
            out += zlib.decompress(blob[at:at + size])
            at += size
        expect = (nb - 1) * head[1] + (head[2] or head[1]) if nb else 0
        assert len(out) == expect, (len(out), expect)
        raw = out
    else:
        data = base64.b64decode(text)
        n = struct.unpack(e + h, data[:hs])[0]
        raw = data[hs:hs + n]
    f = TYPES[vtype]
    return list(struct.unpack(e + f * (len(raw) // struct.calcsize(f)), raw))


def read(path):
    root = ET.parse(path).getroot()
    assert root.tag == "VTKFile" and root.get("type") == "UnstructuredGrid", root.attrib
    pieces = root.findall("./UnstructuredGrid/Piece")
    assert len(pieces) == 1
    arrays = {}
    for parent in ("PointData", "CellData", "Points", "Cells"):
        for a in pieces[0].findall(parent + "/DataArray"):
            name = a.get("Name") if parent != "Points" else "Points"
            if a.get("format") == "ascii":
                conv = float if a.get("type").startswith("Float") else int
                arrays[name] = [conv(v) for v in a.text.split()]
            else:
                assert a.get("format") == "binary", a.get("format")
                arrays[name] = _binary(a.text, root, a.get("type"))
    return dict(pieces[0].attrib), arrays
