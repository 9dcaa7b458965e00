#!/usr/bin/env python3
"""Point lists for tests/cli/points.sh: writes one set of 3D points as a
labelled CSV (comments, quoted labels with commas), a Slicer .fcsv (LPS)
and a Slicer .mrk.json (RAS: x and y negated), and compares what warp
and --landmarks make of them with the plain CSV's.

    points_check.py write PLAIN.csv OUTDIR      the three files from PLAIN
    points_check.py same PLAIN_OUT.csv OTHER_OUT.csv [TOL]
        the coordinates (x, y, z by name) of two warp outputs agree (bit
        for bit unless TOL), and every other column of OTHER survives
    points_check.py labels OTHER_OUT.csv        the labels are the written ones
"""
import csv
import json
import sys


def read(path):
    rows = [r for r in csv.reader(l for l in open(path) if not l.startswith('#'))]
    head = [h.strip().lower() for h in rows[0]]
    return head, rows[1:]


def coords(path):
    head, rows = read(path)
    i = [head.index(c) for c in ('x', 'y', 'z')]
    return [[float(r[k]) for k in i] for r in rows], head, rows


def write(plain, outdir):
    pts, _, _ = coords(plain)
    with open(outdir + '/labelled.csv', 'w') as f:
        f.write('# landmarks of the test, in the template frame (LPS)\n')
        f.write('id,label,x,y,z,note\n')
        for k, p in enumerate(pts):
            f.write('%d,"pt %d, ""left""",%r,%r,%r,kept %d\n' % (k, k, p[0], p[1], p[2], k))
            if k == 3:
                f.write('# a comment between the points\n')
    with open(outdir + '/slicer.fcsv', 'w') as f:
        f.write('# Markups fiducial file version = 4.11\n# CoordinateSystem = LPS\n')
        f.write('# columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID\n')
        for k, p in enumerate(pts):
            f.write('vtkMRMLMarkupsFiducialNode_%d,%r,%r,%r,0,0,0,1,1,1,0,F-%d,,\n'
                    % (k, p[0], p[1], p[2], k))
    doc = {'@schema': 'https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/'
                      'Markups/Resources/Schema/markups-schema-v1.0.3.json#',
           'markups': [{'type': 'Fiducial', 'coordinateSystem': 'RAS', 'coordinateUnits': 'mm',
                        'controlPoints': [{'id': str(k + 1), 'label': 'F-%d' % k,
                                           'position': [-p[0], -p[1], p[2]]}
                                          for k, p in enumerate(pts)]}]}
    with open(outdir + '/slicer.mrk.json', 'w') as f:
        json.dump(doc, f, indent=2)


def same(a, b, tol='0'):
    pa, _, _ = coords(a)
    pb, head, rows = coords(b)
    tol = float(tol)
    assert len(pa) == len(pb), (len(pa), len(pb))
    for p, q in zip(pa, pb):
        assert all(abs(u - v) <= tol for u, v in zip(p, q)), (p, q)
    assert head[-1] == 'inside', head
    print('%d points agree (tolerance %g); columns %s' % (len(pa), tol, ','.join(head)))


def labels(path):
    head, rows = read(path)
    if 'note' in head:
        for k, r in enumerate(rows):
            assert r[head.index('label')] == 'pt %d, "left"' % k, r
            assert r[head.index('note')] == 'kept %d' % k, r
            assert r[head.index('id')] == str(k), r
    else:
        for k, r in enumerate(rows):
            assert r[head.index('label')] == 'F-%d' % k, r
    print('%d labels kept' % len(rows))


if __name__ == '__main__':
    {'write': write, 'same': same, 'labels': labels}[sys.argv[1]](*sys.argv[2:])
