#!/usr/bin/env python3
"""Writes square2d.smmesh from proto/PAYLOAD.md alone (an implementation
independent of proto/sm_payload.c); test_proto_payload checks that the C
writer produces the same bytes and the C reader reads them back.
Run from this folder: python3 make_golden.py"""
import struct
import zlib

dim = 2
coords = [0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0]
vert_refs = [1, 2, 3, 4]
elems = [0, 1, 2, 0, 2, 3]
elem_refs = [10, 11]
facets = [0, 1, 1, 2, 2, 3, 3, 0]
facet_refs = [1, 2, 3, -4]
displacement = [0.5 * x for x in coords]
distance = [-0.25, 0.125, 0.5, -1e-300]
flags = 0x1 | 0x2

nverts, nelems, nfacets = len(vert_refs), len(elem_refs), len(facet_refs)
head = b"SMMESH\0\0" + struct.pack("<6I", 1, dim, nverts, nelems, nfacets, flags)
head += struct.pack("<I", zlib.crc32(head)) + struct.pack("<I", 0)
assert len(head) == 40

body = bytearray(head)


def put(fmt, values):
    body.extend(struct.pack("<%d%s" % (len(values), fmt), *values))
    body.extend(b"\0" * (-len(body) % 8))


put("d", coords)
put("i", vert_refs)
put("I", elems)
put("i", elem_refs)
put("I", facets)
put("i", facet_refs)
put("d", displacement)
put("d", distance)
body.extend(struct.pack("<I", zlib.crc32(bytes(body))))
with open("square2d.smmesh", "wb") as f:
    f.write(bytes(body))
print("square2d.smmesh: %d bytes" % len(body))
