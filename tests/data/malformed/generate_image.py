#!/usr/bin/env python3
"""Regenerates the image-* cases of the malformed-input corpus (label maps:
NIfTI, NRRD, MetaImage, read by sm_image_read; tests/unit/test_malformed.c
runs them like the others).  Kept apart from generate.py, which leaves the
image-* folders to this script.

Run from anywhere: python3 tests/data/malformed/generate_image.py
"""
import gzip
import os
import shutil
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
CASES = {}


def case(name, filename, data, error, status="format"):
    assert name.startswith("image-") and name not in CASES, name
    CASES[name] = (filename, data, error, status)


def nifti1(dims=(4, 3, 2), datatype=2, bitpix=8, pixdim=(1.0, 1.0, 1.0), vox_offset=352.0,
           srow=None, ndim=3, magic=b"n+1\0", data=None, sform=1):
    h = bytearray(352)
    struct.pack_into("<i", h, 0, 348)
    dim = [ndim] + list(dims) + [1] * (7 - len(dims))
    struct.pack_into("<8h", h, 40, *dim)
    struct.pack_into("<hh", h, 70, datatype, bitpix)
    struct.pack_into("<8f", h, 76, 1.0, *pixdim, 0, 0, 0, 0)
    struct.pack_into("<f", h, 108, vox_offset)
    struct.pack_into("<hh", h, 252, 0, sform)
    srow = srow or [pixdim[0], 0, 0, 0, 0, pixdim[1], 0, 0, 0, 0, pixdim[2], 0]
    struct.pack_into("<12f", h, 280, *srow)
    h[344:348] = magic
    n = 1
    for d in dims:
        n *= max(d, 0)
    return bytes(h) + (bytes(n * bitpix // 8) if data is None else data)


def nifti2(dims=(4, 3, 2), vox_offset=544):
    h = bytearray(544)
    struct.pack_into("<i", h, 0, 540)
    h[4:12] = b"n+2\0\r\n\x1a\n"
    struct.pack_into("<hh", h, 12, 2, 8)
    struct.pack_into("<8q", h, 16, 3, *dims, 1, 1, 1, 1)
    struct.pack_into("<8d", h, 104, 1, 1, 1, 1, 0, 0, 0, 0)
    struct.pack_into("<q", h, 168, vox_offset)
    struct.pack_into("<ii", h, 344, 0, 1)
    struct.pack_into("<12d", h, 400, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0)
    return bytes(h) + bytes(24)


def nrrd(fields=None, data=None, drop=(), magic="NRRD0004"):
    f = {"type": "uchar", "dimension": "3", "space": "left-posterior-superior",
         "sizes": "4 3 2", "space directions": "(1,0,0) (0,1,0) (0,0,1)",
         "endian": "little", "encoding": "raw", "space origin": "(0,0,0)"}
    f.update(fields or {})
    head = magic + "\n" + "".join("%s: %s\n" % (k, v) for k, v in f.items() if k not in drop)
    return head.encode() + b"\n" + (bytes(24) if data is None else data)


def mha(fields=None, data=None, drop=()):
    f = {"ObjectType": "Image", "NDims": "3", "BinaryData": "True",
         "BinaryDataByteOrderMSB": "False", "CompressedData": "False",
         "TransformMatrix": "1 0 0 0 1 0 0 0 1", "Offset": "0 0 0",
         "ElementSpacing": "1 1 1", "DimSize": "4 3 2", "ElementType": "MET_UCHAR"}
    f.update(fields or {})
    head = "".join("%s = %s\n" % (k, v) for k, v in f.items() if k not in drop)
    return (head + "ElementDataFile = LOCAL\n").encode() + (bytes(24) if data is None else data)


# NIfTI
case("image-nifti-truncated-header", "input.nii", nifti1()[:200], "truncated NIfTI header")
case("image-nifti-truncated-voxels", "input.nii", nifti1()[:360], "byte 352: 8 bytes of voxel data left")
case("image-nifti-negative-dim", "input.nii", nifti1(dims=(4, -3, 2)), "byte 44: dim[2] = -3")
case("image-nifti-dim0-zero", "input.nii", nifti1(ndim=0), "dim[0] = 0")
case("image-nifti-4d", "input.nii", nifti1(dims=(4, 3, 2, 5), ndim=4), "dim[4] = 5")
case("image-nifti-huge-dims", "input.nii", nifti1(dims=(32767, 32767, 32767), data=bytes(64)),
     "byte 40: 35181150961663 voxels, more than the 4294967296 read")
case("image-nifti-bad-datatype", "input.nii", nifti1(datatype=32, bitpix=64),
     "byte 70: datatype 32")
case("image-nifti-vox-offset-inside-header", "input.nii", nifti1(vox_offset=100.0),
     "byte 108: vox_offset 100")
case("image-nifti-vox-offset-nan", "input.nii", nifti1(vox_offset=float("nan")), "vox_offset nan")
case("image-nifti-zero-pixdim", "input.nii", nifti1(pixdim=(1.0, 0.0, 1.0), sform=0),
     "pixdim[2] = 0")
case("image-nifti-nan-sform", "input.nii", nifti1(srow=[float("nan")] + [0] * 11),
     "voxel-to-world map is not finite")
case("image-nifti-singular-sform", "input.nii", nifti1(srow=[1, 1, 0, 0, 1, 1, 0, 0, 0, 0, 1, 0]),
     "singular")
case("image-nifti-hdr-img-pair", "input.nii", nifti1(magic=b"ni1\0"), "no NIfTI magic")
case("image-nifti-gz-truncated", "input.nii.gz", gzip.compress(nifti1(), mtime=0)[:-20],
     "truncated or corrupt gzip stream")
case("image-nifti2-truncated", "input.nii", nifti2()[:300], "truncated NIfTI-2 header")
case("image-nifti2-huge-dims", "input.nii", nifti2(dims=(1 << 40, 1, 1)),
     "size 1099511627776 along axis 1")

# NRRD
case("image-nrrd-bad-magic", "input.nrrd", nrrd(magic="NRRD0009"), "magic NRRD0001 to NRRD0005")
case("image-nrrd-truncated", "input.nrrd", nrrd()[:-5], "19 bytes of voxel data left")
case("image-nrrd-missing-sizes", "input.nrrd", nrrd(drop=("sizes",)), "no 'sizes' field")
case("image-nrrd-dimension-4", "input.nrrd", nrrd({"dimension": "4"}), "dimension 2 or 3 is read")
case("image-nrrd-2d-three-sizes", "input.nrrd", nrrd({"dimension": "2"}),
     "sizes: two sizes in [1, 2^20] expected (dimension 2)")
case("image-nrrd-2d-3d-directions", "input.nrrd",
     nrrd({"dimension": "2", "sizes": "4 6", "space directions": "(1,0) (0,1)"}),
     "space directions: two finite vectors (x,y,z) expected (dimension 2)")
case("image-nrrd-bad-type", "input.nrrd", nrrd({"type": "complex"}), "unknown or unsupported type")
case("image-nrrd-size-zero", "input.nrrd", nrrd({"sizes": "4 0 2"}), "three sizes in [1, 2^20]")
case("image-nrrd-size-overflow", "input.nrrd", nrrd({"sizes": "4 99999999999999999999 2"}),
     "three sizes")
case("image-nrrd-nan-direction", "input.nrrd",
     nrrd({"space directions": "(nan,0,0) (0,1,0) (0,0,1)"}), "three finite vectors")
case("image-nrrd-singular-directions", "input.nrrd",
     nrrd({"space directions": "(1,0,0) (2,0,0) (0,0,1)"}), "singular")
case("image-nrrd-zero-spacing", "input.nrrd",
     nrrd({"space directions": "(0,0,0) (0,1,0) (0,0,1)"}), "singular")
case("image-nrrd-bad-encoding", "input.nrrd", nrrd({"encoding": "bzip2"}), "encoding raw or gzip")
case("image-nrrd-bad-gzip", "input.nrrd", nrrd({"encoding": "gzip"}, data=b"\x1f\x8b\x08garbage!!"),
     "corrupt compressed voxel data")
case("image-nrrd-gzip-short", "input.nrrd",
     nrrd({"encoding": "gzip"}, data=gzip.compress(bytes(10), mtime=0)), "inflates to 10 bytes")
case("image-nrrd-data-file-list", "input.nhdr", nrrd({"data file": "LIST"}, data=b""),
     "single data file")
case("image-nrrd-data-file-absolute", "input.nhdr", nrrd({"data file": "/etc/passwd"}, data=b""),
     "must be a relative name")
case("image-nrrd-data-file-missing", "input.nhdr", nrrd({"data file": "none.raw"}, data=b""),
     "cannot open", "io")
case("image-nrrd-space-4d", "input.nrrd", nrrd({"space": "right-anterior-superior-time"}),
     "a 3D frame")
case("image-nrrd-long-line", "input.nrrd", nrrd({"content": "x" * 5000}), "header line longer")
case("image-nrrd-not-field", "input.nrrd", nrrd({"type": "uchar\nwhat is this"}),
     "'field: value' line expected")

# MetaImage
case("image-mha-no-data-file", "input.mha", b"ObjectType = Image\nNDims = 3\n",
     "ends without ElementDataFile")
case("image-mha-truncated", "input.mha", mha()[:-4], "20 bytes of voxel data left")
case("image-mha-ndims-4", "input.mha", mha({"NDims": "4"}), "NDims 2 or 3 is read")
case("image-mha-2d-three-sizes", "input.mha",
     mha({"NDims": "2", "TransformMatrix": "1 0 0 1", "Offset": "0 0",
          "ElementSpacing": "1 1"}),
     "DimSize: two sizes in [1, 2^20] expected (NDims 2)")
case("image-mha-dimsize-before-ndims", "input.mha",
     b"ObjectType = Image\nDimSize = 4 3 2\n" + mha(drop=("DimSize", "ObjectType")),
     "NDims must come before")
case("image-mha-bad-type", "input.mha", mha({"ElementType": "MET_FLOAT_ARRAY"}), "ElementType")
case("image-mha-channels", "input.mha", mha({"ElementNumberOfChannels": "3"}), "one channel")
case("image-mha-missing-dimsize", "input.mha", mha(drop=("DimSize",)), "no DimSize")
case("image-mha-nan-spacing", "input.mha", mha({"ElementSpacing": "1 nan 1"}), "ElementSpacing")
case("image-mha-zero-spacing", "input.mha", mha({"ElementSpacing": "1 0 1"}), "singular")
case("image-mha-singular-matrix", "input.mha", mha({"TransformMatrix": "1 0 0 1 0 0 0 0 1"}),
     "singular")
case("image-mha-bad-zlib", "input.mha", mha({"CompressedData": "True"}, data=b"\x78\x9cnotzlib"),
     "corrupt compressed voxel data")
case("image-mha-zlib-short", "input.mha",
     mha({"CompressedData": "True"}, data=zlib.compress(bytes(7))), "inflates to 7 bytes")
case("image-mha-dimsize-huge", "input.mha", mha({"DimSize": "1048576 1048576 1048576"}),
     "more than the 4294967296 read")
case("image-mha-ascii", "input.mha", mha({"BinaryData": "False"}), "BinaryData True")
case("image-unknown-format", "input.img", b"\x00\x01\x02 not an image", "not an image this reads")


def main():
    for name in os.listdir(HERE):
        path = os.path.join(HERE, name)
        if name.startswith("image-") and os.path.isdir(path) and name not in CASES:
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
    print("%d image cases" % len(CASES))


if __name__ == "__main__":
    main()
