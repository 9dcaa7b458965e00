#!/usr/bin/env python3
"""Independent checks of `shapematch sdf --image -o OUT.nii.gz|.nrrd|.mha`
(tests/cli/image_out.sh): the NIfTI read by nibabel, the NRRD and
MetaImage headers parsed here, the values against the exact sphere of
tests/cli/image_shapes.py, the summary's world box against the box of
the selected voxel centres computed with numpy.

    image_out_check.py nifti IN.nii OUT.nii.gz EDT.nrrd
    image_out_check.py same OUT.nii.gz OTHER.nrrd|OTHER.mha
    image_out_check.py box IN.nii STDERR_FILE
"""
import re
import sys

import nibabel
import numpy as np

sys.path.insert(0, __file__.rsplit('/', 1)[0])
import image_shapes  # noqa: E402  (the sphere's centre and radius)

RAS_TO_LPS = np.diag([-1.0, -1.0, 1.0, 1.0])


def centres_lps(img):
    """LPS world coordinates of every voxel centre, in the array's order."""
    i, j, k = np.meshgrid(*[np.arange(n) for n in img.shape[:3]], indexing='ij')
    ijk = np.stack([i, j, k, np.ones_like(i)], axis=-1).astype(float)
    return (ijk @ (RAS_TO_LPS @ img.affine).T)[..., :3]


def sphere(p):
    return np.linalg.norm(p - np.array(image_shapes.CENTRE), axis=-1) - 10.0


def read_nrrd(path):
    raw = open(path, 'rb').read()
    head, data = raw.split(b'\n\n', 1)
    h = dict(line.split(': ', 1) for line in head.decode().splitlines()[1:]
             if ': ' in line and not line.startswith('#'))
    sizes = [int(v) for v in h['sizes'].split()]
    dirs = [[float(x) for x in d.strip('()').split(',')] for d in h['space directions'].split()]
    origin = [float(x) for x in h['space origin'].strip('()').split(',')]
    assert h['type'] == 'float' and h['encoding'] == 'raw' and h['endian'] == 'little'
    assert h['space'] == 'left-posterior-superior'
    m = np.eye(4)
    m[:3, :3] = np.array(dirs).T
    m[:3, 3] = origin
    return m, np.frombuffer(data, '<f4').reshape(sizes[::-1]).transpose(2, 1, 0)


def read_mha(path):
    raw = open(path, 'rb').read()
    end = raw.index(b'ElementDataFile = LOCAL\n') + len(b'ElementDataFile = LOCAL\n')
    h = dict(line.split(' = ', 1) for line in raw[:end].decode().splitlines())
    assert h['ElementType'] == 'MET_FLOAT' and h['CompressedData'] == 'False'
    dims = [int(v) for v in h['DimSize'].split()]
    tm = np.array([float(v) for v in h['TransformMatrix'].split()]).reshape(3, 3)
    sp = np.array([float(v) for v in h['ElementSpacing'].split()])
    m = np.eye(4)
    m[:3, :3] = tm.T * sp   # row a of TransformMatrix: axis a's direction (ITK)
    m[:3, 3] = [float(v) for v in h['Offset'].split()]
    return m, np.frombuffer(raw[end:], '<f4').reshape(dims[::-1]).transpose(2, 1, 0)


def nifti(src, out, edt):
    a, b = nibabel.load(src), nibabel.load(out)
    assert b.shape == a.shape, (b.shape, a.shape)
    assert np.allclose(b.affine, a.affine, atol=1e-6), (b.affine, a.affine)
    q = b.header.get_qform(coded=True)
    assert q[1] > 0 and np.allclose(q[0], a.affine, atol=1e-5), q
    d = b.get_fdata(dtype=np.float64)
    exact = sphere(centres_lps(b))
    h = max(image_shapes.SPACING)
    near = np.abs(exact) < 2 * h
    err = d - exact
    # the voxel-centre EDT (--edt-out, on a crop of the same grid) on the
    # same band: what the written distance must beat
    em, ev = read_nrrd(edt)
    off = np.rint(np.linalg.solve((RAS_TO_LPS @ a.affine), em)[:3, 3]).astype(int)
    # image index s is crop index s - off
    sl = tuple(slice(max(0, o), min(n, ev.shape[c] + o)) for c, (o, n) in enumerate(zip(off, d.shape)))
    el = tuple(slice(s.start - o, s.stop - o) for s, o in zip(sl, off))
    band = near[sl]
    rms_out = float(np.sqrt(np.mean(err[sl][band] ** 2)))
    rms_edt = float(np.sqrt(np.mean((ev[el].astype(float) - exact[sl])[band] ** 2)))
    far = float(np.max(np.abs(err)))
    sign_ok = bool(np.all(np.sign(d[np.abs(exact) > h]) == np.sign(exact[np.abs(exact) > h])))
    print('near the surface: rms %.4f (voxel-centre EDT %.4f); max |error| %.4f over %d voxels'
          % (rms_out, rms_edt, far, d.size))
    assert rms_out <= 0.5 * rms_edt, 'not better than half the voxel-centre EDT'
    assert far <= h, 'max error over the grid above one voxel'
    assert sign_ok, 'a sign differs more than a voxel from the surface'


def same(out, other):
    b = nibabel.load(out)
    m, v = (read_nrrd if other.endswith('.nrrd') else read_mha)(other)
    assert np.allclose(m, RAS_TO_LPS @ b.affine, atol=1e-5), (m, RAS_TO_LPS @ b.affine)
    assert np.array_equal(v, np.asarray(b.dataobj, dtype=np.float32)), 'values differ'
    print('%s: the same geometry and values as %s' % (other, out))


def box(src, err_file):
    a = nibabel.load(src)
    p = centres_lps(a)[np.asarray(a.dataobj) != 0]
    lo, hi = p.min(axis=0), p.max(axis=0)
    text = open(err_file).read()
    nums = re.search(r'world box \(LPS\) \[(\S+), (\S+)\] x \[(\S+), (\S+)\] x \[(\S+), (\S+)\]',
                     text)
    got = np.array([float(v) for v in nums.groups()]).reshape(3, 2)
    want = np.stack([lo, hi], axis=1)
    print('world box printed %s, voxel centres %s' % (got.tolist(), want.round(5).tolist()))
    assert np.allclose(got, want, atol=1e-4 * (1 + np.abs(want))), 'world box differs'


if __name__ == '__main__':
    {'nifti': nifti, 'same': same, 'box': box}[sys.argv[1]](*sys.argv[2:])
