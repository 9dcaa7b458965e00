#!/usr/bin/env python3
"""Analytic shapes rasterised on an oblique, anisotropic grid and written
as NIfTI-1 (sform; qform; gzip), NIfTI-2, NRRD (raw, gzip, RAS space,
big-endian int16, detached .nhdr + .raw.gz) and MetaImage (.mha raw and
zlib, .mhd + .raw, float32), all of the same array in the same LPS place,
for tests/cli/image.sh.  Pure Python (struct, zlib, gzip): no numpy.

    image_shapes.py write DIR SHAPE     SHAPE: sphere | ellipsoid
    image_shapes.py check DIR SHAPE SPACE OUT/background.mesh OUT/background.sol
        distance at the background vertices against the exact one
    image_shapes.py edt DIR EDT.nrrd    the EDT grid against brute force
    image_shapes.py solcmp A.sol B.sol TOL
    image_shapes.py edtbrute EDT.nrrd IMAGE.nrrd
        the signed EDT of an unsmoothed mask against brute force, sampled
"""
import gzip
import math
import struct
import sys
import zlib

DIMS = (34, 30, 22)
SPACING = (1.0, 1.25, 1.75)
ORIGIN = (-12.5, 20.25, -7.0)
CENTRE = (4.0, 39.0, 9.0)      # LPS, mm


def f32(x):
    return struct.unpack('<f', struct.pack('<f', x))[0]


def rotation():
    """An oblique proper rotation (about the axis (1, 2, 2)/3 by 25
    degrees), its entries rounded to float32 so that every format (NIfTI-1
    stores float32) carries the same numbers."""
    ax = (1 / 3, 2 / 3, 2 / 3)
    t = math.radians(25)
    c, s = math.cos(t), math.sin(t)
    x, y, z = ax
    r = [[c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
         [y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s],
         [z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)]]
    return r


def affine():
    """rows of the 3x4 voxel -> LPS map, float32-exact."""
    r = rotation()
    return [[f32(r[row][col] * SPACING[col]) for col in range(3)] + [f32(ORIGIN[row])]
            for row in range(3)]


def world(m, i, j, k):
    return [m[r][0] * i + m[r][1] * j + m[r][2] * k + m[r][3] for r in range(3)]


def exact(shape, p):
    """signed distance to the shape, negative inside (the ellipsoid's is
    its level function scaled: exact on the axes; used for the mask only)."""
    d = [p[k] - CENTRE[k] for k in range(3)]
    if shape == 'sphere':
        return math.sqrt(sum(v * v for v in d)) - 10.0
    a = (12.0, 9.0, 7.0)
    q = math.sqrt(sum((d[k] / a[k]) ** 2 for k in range(3)))
    return (q - 1) * min(a)


def voxels(shape):
    m = affine()
    out = bytearray(DIMS[0] * DIMS[1] * DIMS[2])
    n = 0
    for k in range(DIMS[2]):
        for j in range(DIMS[1]):
            for i in range(DIMS[0]):
                out[n] = 1 if exact(shape, world(m, i, j, k)) <= 0 else 0
                n += 1
    return bytes(out)


def typed(data, fmt):
    return b''.join(struct.pack(fmt, v) for v in data)


def nifti1(data, sform=True, datatype=2, bitpix=8):
    m = affine()
    ras = [[-v for v in m[0]], [-v for v in m[1]], m[2]]
    h = bytearray(352)
    struct.pack_into('<i', h, 0, 348)
    struct.pack_into('<8h', h, 40, 3, *DIMS, 1, 1, 1, 1)
    struct.pack_into('<hh', h, 70, datatype, bitpix)
    qfac = 1.0
    struct.pack_into('<8f', h, 76, qfac, *SPACING, 0, 0, 0, 0)
    struct.pack_into('<f', h, 108, 352.0)
    struct.pack_into('<f', h, 112, 1.0)
    if sform:
        struct.pack_into('<hh', h, 252, 0, 1)
        for row in range(3):
            struct.pack_into('<4f', h, 280 + 16 * row, *ras[row])
    else:
        # the quaternion of the RAS rotation (det +1)
        r = [[ras[row][col] / SPACING[col] for col in range(3)] for row in range(3)]
        a = 0.5 * math.sqrt(max(0.0, 1 + r[0][0] + r[1][1] + r[2][2]))
        b = (r[2][1] - r[1][2]) / (4 * a)
        c = (r[0][2] - r[2][0]) / (4 * a)
        d = (r[1][0] - r[0][1]) / (4 * a)
        struct.pack_into('<hh', h, 252, 1, 0)
        struct.pack_into('<6f', h, 256, b, c, d, ras[0][3], ras[1][3], ras[2][3])
    h[344:348] = b'n+1\0'
    return bytes(h) + data


def nifti2(data):
    m = affine()
    ras = [[-v for v in m[0]], [-v for v in m[1]], m[2]]
    h = bytearray(544)
    struct.pack_into('<i', h, 0, 540)
    h[4:12] = b'n+2\0\r\n\x1a\n'
    struct.pack_into('<hh', h, 12, 2, 8)
    struct.pack_into('<8q', h, 16, 3, *DIMS, 1, 1, 1, 1)
    struct.pack_into('<8d', h, 104, 1.0, *SPACING, 0, 0, 0, 0)
    struct.pack_into('<q', h, 168, 544)
    struct.pack_into('<d', h, 176, 1.0)
    struct.pack_into('<ii', h, 344, 0, 2)
    for row in range(3):
        struct.pack_into('<4d', h, 400 + 32 * row, *ras[row])
    return bytes(h) + data


def nrrd_header(typ, enc, space='left-posterior-superior', endian='little', extra=''):
    m = affine()
    flip = [-1, -1, 1] if space == 'right-anterior-superior' else [1, 1, 1]
    dirs = ' '.join('(%r,%r,%r)' % tuple(flip[r] * m[r][c] for r in range(3)) for c in range(3))
    origin = '(%r,%r,%r)' % tuple(flip[r] * m[r][3] for r in range(3))
    return ('NRRD0004\n# shapematch test image\ntype: %s\ndimension: 3\nspace: %s\n'
            'sizes: %d %d %d\nspace directions: %s\nkinds: domain domain domain\n'
            'endian: %s\nencoding: %s\nspace origin: %s\n%s' %
            (typ, space, *DIMS, dirs, endian, enc, origin, extra)).encode()


def mha_header(etype, compressed, datafile='LOCAL', extra=''):
    m = affine()
    tm = ' '.join(repr(m[r][c] / SPACING[c]) for c in range(3) for r in range(3))
    return ('ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n'
            'CompressedData = %s\n%sTransformMatrix = %s\nOffset = %r %r %r\n'
            'AnatomicalOrientation = RAI\nElementSpacing = %r %r %r\nDimSize = %d %d %d\n'
            'ElementType = %s\nElementDataFile = %s\n' %
            ('True' if compressed else 'False', extra, tm, m[0][3], m[1][3], m[2][3], *SPACING,
             *DIMS, etype, datafile)).encode()


def write(d, shape):
    data = voxels(shape)
    files = {}
    files['s1.nii'] = nifti1(data)
    files['q1.nii'] = nifti1(data, sform=False)
    files['s1.nii.gz'] = gzip.compress(nifti1(data), mtime=0)
    files['s2.nii'] = nifti2(data)
    files['raw.nrrd'] = nrrd_header('uchar', 'raw') + b'\n' + data
    files['gz.nrrd'] = nrrd_header('uint8', 'gzip') + b'\n' + gzip.compress(data, mtime=0)
    files['ras.nrrd'] = nrrd_header('unsigned char', 'raw', 'right-anterior-superior') + b'\n' + data
    files['be16.nrrd'] = nrrd_header('short', 'raw', endian='big') + b'\n' + typed(data, '>h')
    files['det.nhdr'] = nrrd_header('uchar', 'gzip', extra='data file: det.raw.gz\n')
    files['det.raw.gz'] = gzip.compress(data, mtime=0)
    files['raw.mha'] = mha_header('MET_UCHAR', False) + data
    files['z.mha'] = mha_header('MET_USHORT', True) + zlib.compress(typed(data, '<H'))
    files['f32.mha'] = mha_header('MET_FLOAT', False) + typed(data, '<f')
    files['det.mhd'] = mha_header('MET_UCHAR', False, 'det.raw')
    files['det.raw'] = data
    for name, content in files.items():
        with open('%s/%s' % (d, name), 'wb') as f:
            f.write(content)
    print(sum(data), 'voxels inside')


def read_mesh_vertices(path):
    with open(path) as f:
        tok = f.read().split()
    i = tok.index('Vertices')
    n = int(tok[i + 1])
    return [[float(tok[i + 2 + 4 * v + c]) for c in range(3)] for v in range(n)]


def read_sol(path):
    with open(path) as f:
        tok = f.read().split()
    i = tok.index('SolAtVertices')
    n = int(tok[i + 1])
    return [float(t) for t in tok[i + 4:i + 4 + n]]


def check(d, shape, space, mesh, sol):
    """RMS and max error against the exact sphere near its surface; the
    voxel-centre EDT's error on the same points for comparison."""
    x = read_mesh_vertices(mesh)
    v = read_sol(sol)
    flip = [-1, -1, 1] if space == 'ras' else [1, 1, 1]
    h = max(SPACING)
    err = []
    for p, dv in zip(x, v):
        q = [flip[k] * p[k] for k in range(3)]   # back to LPS
        e = exact(shape, q)
        if abs(e) < 2 * h:
            err.append(dv - e)
    rms = math.sqrt(sum(e * e for e in err) / len(err))
    print('near-surface vertices %d: rms %.4f max %.4f (mm; spacing up to %g)' %
          (len(err), rms, max(abs(e) for e in err), h))
    return rms


def read_nrrd_floats(path):
    with open(path, 'rb') as f:
        raw = f.read()
    head, data = raw.split(b'\n\n', 1)
    hdr = dict(l.split(': ', 1) for l in head.decode().split('\n')[1:])
    n = [int(t) for t in hdr['sizes'].split()]
    vals = struct.unpack('<%df' % (n[0] * n[1] * n[2]), data)
    dirs = [[float(t) for t in v.strip('()').split(',')] for v in hdr['space directions'].split()]
    origin = [float(t) for t in hdr['space origin'].strip('()').split(',')]
    return n, vals, dirs, origin


def edt_check(path, shape):
    """The EDT grid: voxel-centre EDT of the thresholded smoothed mask; at
    voxel centres away from the boundary it is within a voxel of the exact
    distance (what an EDT of a sampled shape gives), and its error there
    is printed for the report."""
    n, vals, dirs, origin = read_nrrd_floats(path)
    errs = []
    for k in range(n[2]):
        for j in range(n[1]):
            for i in range(n[0]):
                p = [origin[r] + dirs[0][r] * i + dirs[1][r] * j + dirs[2][r] * k for r in range(3)]
                e = exact(shape, p)
                if abs(e) < 2 * max(SPACING):
                    errs.append(vals[i + n[0] * (j + n[1] * k)] - e)
    rms = math.sqrt(sum(e * e for e in errs) / len(errs))
    print('voxel-centre EDT near the surface: %d voxels, rms %.4f max %.4f' %
          (len(errs), rms, max(abs(e) for e in errs)))
    return rms


def nrrd_file(path):
    with open(path, 'rb') as f:
        raw = f.read()
    head, data = raw.split(b'\n\n', 1)
    hdr = dict(l.split(': ', 1) for l in head.decode().split('\n')[1:] if ': ' in l)
    n = [int(t) for t in hdr['sizes'].split()]
    dirs = [[float(t) for t in v.strip('()').split(',')] for v in hdr['space directions'].split()]
    origin = [float(t) for t in hdr['space origin'].strip('()').split(',')]
    return n, data, dirs, origin


def edt_brute(edt_path, image_path):
    """Every 7th voxel of the crop: its signed EDT value against the
    distance to the nearest voxel centre of the other class, found among
    that class's boundary voxels (a nearest one always has a neighbour of
    the other class: a step toward the query would otherwise be nearer)."""
    n, data, dirs, origin = nrrd_file(edt_path)
    vals = struct.unpack('<%df' % (n[0] * n[1] * n[2]), data)
    n0, data0, dirs0, origin0 = nrrd_file(image_path)
    # the crop's first voxel in the image's indices: dirs equal, solve
    # origin = origin0 + sum_a off_a dirs0[a] by Cramer's rule
    m = [[dirs0[a][r] for a in range(3)] for r in range(3)]
    rhs = [origin[r] - origin0[r] for r in range(3)]

    def det(a):
        return (a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
                a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
                a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]))
    d = det(m)
    off = []
    for a in range(3):
        ma = [[rhs[r] if c == a else m[r][c] for c in range(3)] for r in range(3)]
        off.append(round(det(ma) / d))
    h = [math.sqrt(sum(v * v for v in dirs[a])) for a in range(3)]

    def inside(i, j, k):
        p = (i + off[0], j + off[1], k + off[2])
        if not all(0 <= p[a] < n0[a] for a in range(3)):
            return False
        return data0[p[0] + n0[0] * (p[1] + n0[1] * p[2])] != 0
    cls = {}
    for k in range(n[2]):
        for j in range(n[1]):
            for i in range(n[0]):
                cls[(i, j, k)] = inside(i, j, k)
    border = {True: [], False: []}
    for (i, j, k), c in cls.items():
        for di, dj, dk in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)):
            q = cls.get((i + di, j + dj, k + dk))
            if q is not None and q != c:
                border[c].append((i * h[0], j * h[1], k * h[2]))
                break
    worst, count = 0.0, 0
    total = n[0] * n[1] * n[2]
    for v in range(0, total, 7):
        i, j, k = v % n[0], (v // n[0]) % n[1], v // (n[0] * n[1])
        c = cls[(i, j, k)]
        x = (i * h[0], j * h[1], k * h[2])
        best = min((x[0] - p[0]) ** 2 + (x[1] - p[1]) ** 2 + (x[2] - p[2]) ** 2
                   for p in border[not c])
        want = -math.sqrt(best) if c else math.sqrt(best)
        worst = max(worst, abs(vals[v] - want))
        count += 1
    print('signed EDT against brute force: %d voxels of %d, max difference %.3g' %
          (count, total, worst))
    return worst


def main():
    cmd = sys.argv[1]
    if cmd == 'write':
        write(sys.argv[2], sys.argv[3])
    elif cmd == 'check':
        rms = check(sys.argv[2], sys.argv[3], sys.argv[4], sys.argv[5], sys.argv[6])
        limit = float(sys.argv[7])
        if not rms <= limit:
            sys.exit('rms %.4f above %.4f' % (rms, limit))
    elif cmd == 'edt':
        print('%.6f' % edt_check(sys.argv[2], sys.argv[3]))
    elif cmd == 'edtbrute':
        if not edt_brute(sys.argv[2], sys.argv[3]) < 1e-4:
            sys.exit('the EDT differs from brute force')
    elif cmd == 'solcmp':
        a, b, tol = read_sol(sys.argv[2]), read_sol(sys.argv[3]), float(sys.argv[4])
        if len(a) != len(b):
            sys.exit('%d against %d values' % (len(a), len(b)))
        worst = max(abs(x - y) for x, y in zip(a, b))
        if worst > tol:
            sys.exit('values differ by up to %g (tolerance %g)' % (worst, tol))
        print('%d values, max difference %g' % (len(a), worst))


if __name__ == '__main__':
    main()
