#!/usr/bin/env python3
"""A VTK XML (.vtu) of zlib-compressed zeros (issue 37): its Points are
npoints * 3 Float32 zeros in 64 KiB zlib blocks (appended raw), a file
about 1/1000 of what it declares.  Used by tests/data/malformed/generate.py
(the reader's case) and tests/integration/daemon_warp_bounds.sh.

zlib_bomb.py OUT.vtu NPOINTS"""
import struct
import sys
import zlib


def zlib_bomb_vtu(npoints):
    total, bs = npoints * 12, 1 << 16
    nb = (total + bs - 1) // bs
    last = total - (nb - 1) * bs
    blocks = [zlib.compress(b"\0" * bs, 9)] * (nb - 1) + [zlib.compress(b"\0" * last, 9)]
    head = struct.pack("<%dI" % (3 + nb), nb, bs, last if last != bs else 0,
                       *[len(b) for b in blocks])
    return (b'<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
            b'byte_order="LittleEndian" header_type="UInt32" compressor="vtkZLibDataCompressor">'
            b'\n<UnstructuredGrid>\n<Piece NumberOfPoints="%d" NumberOfCells="1">\n<Points>\n'
            b'<DataArray type="Float32" NumberOfComponents="3" format="appended" offset="0"/>\n'
            b'</Points>\n<Cells>\n<DataArray type="Int32" Name="connectivity" format="ascii">'
            b'0 1 2 3</DataArray>\n<DataArray type="Int32" Name="offsets" format="ascii">4'
            b'</DataArray>\n<DataArray type="UInt8" Name="types" format="ascii">10</DataArray>'
            b'\n</Cells>\n</Piece>\n</UnstructuredGrid>\n<AppendedData encoding="raw">\n_'
            % npoints + head + b"".join(blocks) + b"\n</AppendedData>\n</VTKFile>\n")


if __name__ == "__main__":
    with open(sys.argv[1], "wb") as f:
        f.write(zlib_bomb_vtu(int(sys.argv[2])))
