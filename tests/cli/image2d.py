#!/usr/bin/env python3
"""A disk of radius R = 0.32 about (0.5, 0.5) (LPS, the 2D example's
frame) rasterised on an oblique (rotated 20 degrees), anisotropic 2D grid
and written as truly 2D images: NIfTI-1 (dim[0] = 2, sform), NRRD
(dimension 2, space dimension 2) and MetaImage (NDims 2), all of the
same array in the same place, for tests/cli/image2d.sh; and a 3D image
(one more axis of 3 slices) for the dimension messages.  Pure Python.

    image2d.py write DIR
    image2d.py radius RESULT.mesh    the largest | |x - c| - R | over the
                                     result's boundary vertices (Edges of
                                     reference 1) against the exact circle
"""
import math
import struct
import sys

N = (66, 52)
H = (0.015625, 0.0234375)          # binary fractions: exact in float32
ORIGIN = (0.25, -0.25)
C, R = (0.5, 0.5), 0.32
T = math.radians(20)


def f32(x):
    return struct.unpack('<f', struct.pack('<f', x))[0]


def affine():
    """rows x, y of the 2x3 index -> LPS map, float32-exact."""
    c, s = math.cos(T), math.sin(T)
    rot = [[c, -s], [s, c]]
    return [[f32(rot[r][k] * H[k]) for k in range(2)] + [f32(ORIGIN[r])] for r in range(2)]


def voxels():
    m = affine()
    out = bytearray()
    for j in range(N[1]):
        for i in range(N[0]):
            x = m[0][0] * i + m[0][1] * j + m[0][2]
            y = m[1][0] * i + m[1][1] * j + m[1][2]
            out.append(1 if math.hypot(x - C[0], y - C[1]) < R else 0)
    return bytes(out)


def nifti(data, ndim=2, nz=1):
    m = affine()
    ras = [[-v for v in m[0][:2]] + [0.0, -m[0][2]], [-v for v in m[1][:2]] + [0.0, -m[1][2]],
           [0.0, 0.0, 1.0, 0.0]]
    h = bytearray(352)
    struct.pack_into('<i', h, 0, 348)
    struct.pack_into('<8h', h, 40, ndim, N[0], N[1], nz, 1, 1, 1, 1)
    struct.pack_into('<hh', h, 70, 2, 8)
    struct.pack_into('<8f', h, 76, 1.0, H[0], H[1], 1.0, 0, 0, 0, 0)
    struct.pack_into('<f', h, 108, 352.0)
    struct.pack_into('<f', h, 112, 1.0)
    struct.pack_into('<hh', h, 252, 0, 1)
    for row in range(3):
        struct.pack_into('<4f', h, 280 + 16 * row, *ras[row])
    h[344:348] = b'n+1\0'
    return bytes(h) + data


def nrrd(data):
    m = affine()
    dirs = ' '.join('(%r,%r)' % (m[0][k], m[1][k]) for k in range(2))
    return ('NRRD0004\n# a 2D label map\ntype: uchar\ndimension: 2\nspace dimension: 2\n'
            'sizes: %d %d\nspace directions: %s\nkinds: domain domain\nendian: little\n'
            'encoding: raw\nspace origin: (%r,%r)\n\n' % (*N, dirs, m[0][2], m[1][2])).encode() + data


def mha(data):
    m = affine()
    tm = ' '.join(repr(m[r][k] / H[k]) for k in range(2) for r in range(2))
    return ('ObjectType = Image\nNDims = 2\nBinaryData = True\nBinaryDataByteOrderMSB = False\n'
            'CompressedData = False\nTransformMatrix = %s\nOffset = %r %r\n'
            'ElementSpacing = %r %r\nDimSize = %d %d\nElementType = MET_UCHAR\n'
            'ElementDataFile = LOCAL\n' % (tm, m[0][2], m[1][2], *H, *N)).encode() + data


def write(d):
    data = voxels()
    files = {'disk.nii': nifti(data), 'disk.nrrd': nrrd(data), 'disk.mha': mha(data),
             'disk3.nii': nifti(data * 3, ndim=3, nz=3)}
    for name, content in files.items():
        with open('%s/%s' % (d, name), 'wb') as f:
            f.write(content)
    print(sum(data), 'pixels inside')


def radius(path):
    tok = open(path).read().split()
    dim = int(tok[tok.index('Dimension') + 1])
    i = tok.index('Vertices')
    x = [[float(tok[i + 2 + (dim + 1) * v + k]) for k in range(2)] for v in range(int(tok[i + 1]))]
    j = tok.index('Edges')
    b = set()
    for e in range(int(tok[j + 1])):
        a, c, ref = (int(t) for t in tok[j + 2 + 3 * e:j + 5 + 3 * e])
        if ref == 1:
            b.update((a - 1, c - 1))
    err = [math.dist(x[v], C) - R for v in b]
    return max(abs(e) for e in err), math.sqrt(sum(e * e for e in err) / len(err))


if __name__ == '__main__':
    if sys.argv[1] == 'write':
        write(sys.argv[2])
    else:
        print('%.3e %.3e' % radius(sys.argv[2]))
