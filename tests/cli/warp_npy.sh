#!/usr/bin/env bash
# `shapematch warp --points` with NumPy .npy files and --outside, on the
# 3D example's ball under a known affine map (tests/cli/warp_check.py
# make), where the piecewise-linear map is A x + b exactly, inside and
# outside (the nearest element's affine map is the same map): every
# answer checked against A x + b computed by numpy, the .npy files read
# and written by numpy itself (numpy.save, numpy.load):
#   - float64 and float32 .npy in, .npy and CSV out; numpy.load reads our
#     .npy, which is byte for byte numpy.save's; the .npy answer equals the
#     CSV answer bit for bit;
#   - --outside extrapolate, flag (NaN rows exactly where inside is 0, the
#     other rows unchanged), skip (only the inside rows, in order, and the
#     count on stderr), for CSV and .npy; --strict names the .npy row;
#   - refused inputs with their messages: big-endian, integers, Fortran
#     order, 4 columns, 1-D, truncated data, no magic; usage errors.
source "$(dirname "$0")/../lib/cli.sh"
PY=/usr/bin/python3 # Debian's, with python3-numpy
CHECK="python3 $ROOT/tests/cli/warp_check.py"
T3=$ROOT/examples/3d/template.mesh
if ! "$PY" -c 'import numpy' 2>/dev/null; then
    skip "python3-numpy not installed (make deps installs it)"
    exit 0
fi
R=$WORK/res
mkdir -p "$R"
$CHECK make "$T3" "$R" affine
# points in and around the ball of radius 0.3 about (0.5, 0.5, 0.5):
# about half outside it
"$PY" - "$WORK" <<'PY'
import sys
import numpy as np
w = sys.argv[1]
rng = np.random.default_rng(7)
p = 0.5 + rng.uniform(-0.45, 0.45, size=(400, 3))
np.save(w + "/p.npy", p)
np.save(w + "/p32.npy", p.astype("<f4"))
np.savetxt(w + "/p.csv", p, delimiter=",", fmt="%.17g", header="x,y,z", comments="")
np.save(w + "/be.npy", p.astype(">f8"))
np.save(w + "/i4.npy", (p * 100).astype("<i4"))
np.save(w + "/fortran.npy", np.asfortranarray(p))
np.save(w + "/four.npy", np.hstack([p, p[:, :1]]))
np.save(w + "/flat.npy", p[:, 0])
open(w + "/trunc.npy", "wb").write(open(w + "/p.npy", "rb").read()[:-5])
open(w + "/nomagic.npy", "wb").write(b"NUMPY\x01\x00" + b"x" * 100)
PY
# the expected images, by numpy: A x + b (warp_check.py's A and b)
cat >"$WORK/check.py" <<'PY'
import sys
import numpy as np
A = np.array([[1.2, 0.3, -0.1], [-0.2, 0.9, 0.25], [0.05, -0.15, 1.1]])
B = np.array([0.5, -1.0, 2.0])
def csv(path):
    a = np.genfromtxt(path, delimiter=",", names=True)
    return np.stack([a["x"], a["y"], a["z"]], axis=1), a["inside"].astype(int)
def mapped(p):
    return p @ A.T + B
cmd = sys.argv[1]
if cmd == "affine":  # OUT.npy images of IN.npy: A x + b to 1e-12
    got, p = np.load(sys.argv[2]), np.load(sys.argv[3]).astype(float)
    assert got.dtype == np.float64 and got.shape == p.shape, (got.dtype, got.shape)
    err = np.abs(got - mapped(p)).max()
    assert err < 1e-12, err
elif cmd == "numpy":  # our .npy byte for byte numpy.save's of the same array
    import io
    raw = open(sys.argv[2], "rb").read()
    buf = io.BytesIO()
    np.save(buf, np.load(sys.argv[2]))
    assert buf.getvalue() == raw, (buf.getvalue()[:80], raw[:80])
elif cmd == "same":  # OUT.npy = OUT.csv's coordinates, bit for bit
    a, (b, _) = np.load(sys.argv[2]), csv(sys.argv[3])
    assert a.shape == b.shape and (a.view(np.uint64) == b.view(np.uint64)).all()
elif cmd == "flag":  # NaN rows exactly where inside is 0, the rest as extrapolated
    ref, inside = csv(sys.argv[2])
    got = np.load(sys.argv[3]) if sys.argv[3].endswith(".npy") else csv(sys.argv[3])[0]
    assert 0 < inside.sum() < len(inside), "inside and outside points"
    nan = np.isnan(got).all(axis=1)
    assert (nan == (inside == 0)).all() and not np.isnan(got[~nan]).any()
    assert (got[~nan].view(np.uint64) == ref[~nan].view(np.uint64)).all()
elif cmd == "skip":  # the inside rows only, in order
    ref, inside = csv(sys.argv[2])
    got = np.load(sys.argv[3]) if sys.argv[3].endswith(".npy") else csv(sys.argv[3])[0]
    keep = ref[inside == 1]
    assert got.shape == keep.shape, (got.shape, keep.shape)
    assert (got.view(np.uint64) == keep.view(np.uint64)).all()
PY
C="$PY $WORK/check.py"
expect_ok "CSV in, CSV out" "$BIN" warp --result "$R" --points "$WORK/p.csv" -o "$WORK/ref.csv"
expect_ok "float64 .npy in, .npy out" "$BIN" warp --result "$R" --points "$WORK/p.npy" \
    -o "$WORK/out.npy"
expect_ok "numpy.load reads the answer: A x + b, inside and outside (to 1e-12)" \
    $C affine "$WORK/out.npy" "$WORK/p.npy"
expect_ok ".npy answer = CSV answer, bit for bit" $C same "$WORK/out.npy" "$WORK/ref.csv"
expect_ok ".npy answer = numpy.save's file of the same array, byte for byte" \
    $C numpy "$WORK/out.npy"
expect_ok "float32 .npy in" "$BIN" warp --result "$R" --points "$WORK/p32.npy" -o "$WORK/o32.npy"
expect_ok "float32: A x + b of the float32 values" $C affine "$WORK/o32.npy" "$WORK/p32.npy"
expect_ok ".npy in, CSV out" "$BIN" warp --result "$R" --points "$WORK/p.npy" -o "$WORK/n2c.csv"
if cmp -s "$WORK/n2c.csv" "$WORK/ref.csv"; then
    ok ".npy in, CSV out = CSV in, CSV out, byte for byte"
else
    not_ok ".npy in, CSV out = CSV in, CSV out, byte for byte" "$(diff "$WORK/n2c.csv" "$WORK/ref.csv" | head -5)"
fi
for ext in csv npy; do
    expect_ok "--outside flag ($ext)" "$BIN" warp --result "$R" --points "$WORK/p.npy" \
        --outside flag -o "$WORK/flag.$ext"
    expect_ok "flag ($ext): NaN exactly where inside is 0, the rest unchanged" \
        $C flag "$WORK/ref.csv" "$WORK/flag.$ext"
    "$BIN" warp --result "$R" --points "$WORK/p.npy" --outside skip -o "$WORK/skip.$ext" \
        2>"$WORK/skip.err"
    expect_ok "skip ($ext): the inside rows only, in order" $C skip "$WORK/ref.csv" "$WORK/skip.$ext"
    nout=$(awk -F, 'NR > 1 && $4 == 0' "$WORK/ref.csv" | wc -l)
    check "skip ($ext): stderr says $nout skipped" \
        grep -q "400 points forward, $nout outside the template (skipped" "$WORK/skip.err"
done
expect_ok "--outside extrapolate is the default" "$BIN" warp --result "$R" \
    --points "$WORK/p.csv" --outside extrapolate -o "$WORK/ext.csv"
check "extrapolate = no option, byte for byte" cmp -s "$WORK/ext.csv" "$WORK/ref.csv"
expect_fail "--strict names the .npy row" 2 "points\[[0-9]*\]: point (.*) is outside the template" \
    "$BIN" warp --result "$R" --points "$WORK/p.npy" --strict -o "$WORK/x.npy"

expect_fail "big-endian refused" 2 "descr '>f8': expected '<f8' (float64) or '<f4'" \
    "$BIN" warp --result "$R" --points "$WORK/be.npy" -o "$WORK/x.csv"
expect_fail "integers refused" 2 "descr '<i4'" \
    "$BIN" warp --result "$R" --points "$WORK/i4.npy" -o "$WORK/x.csv"
expect_fail "Fortran order refused" 2 "Fortran-order array: save np.ascontiguousarray" \
    "$BIN" warp --result "$R" --points "$WORK/fortran.npy" -o "$WORK/x.csv"
expect_fail "4 columns refused" 2 "shape (400, 4): expected a 2-D array" \
    "$BIN" warp --result "$R" --points "$WORK/four.npy" -o "$WORK/x.csv"
expect_fail "1-D refused" 2 "shape (400,): expected" \
    "$BIN" warp --result "$R" --points "$WORK/flat.npy" -o "$WORK/x.csv"
expect_fail "truncated data refused" 2 "needs 9600 bytes of data, the file has 9595" \
    "$BIN" warp --result "$R" --points "$WORK/trunc.npy" -o "$WORK/x.csv"
expect_fail "no magic refused" 2 "not a NumPy .npy file" \
    "$BIN" warp --result "$R" --points "$WORK/nomagic.npy" -o "$WORK/x.csv"
expect_fail "--outside: a bad name" 1 "expected extrapolate, flag or skip" \
    "$BIN" warp --result "$R" --points "$WORK/p.npy" --outside nearest -o "$WORK/x.csv"
expect_fail "--outside skip with --strict" 1 "give --strict or --outside skip, not both" \
    "$BIN" warp --result "$R" --points "$WORK/p.npy" --outside skip --strict -o "$WORK/x.csv"
expect_fail "--outside flag with --mesh" 1 "is for --points" \
    "$BIN" warp --result "$R" --mesh "$T3" --outside flag -o "$WORK/x.mesh"
[ "$failed" = 0 ]
