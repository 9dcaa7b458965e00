#!/usr/bin/env python3
"""The stall rule's figures on Gmsh-made cases of other shapes and sizes
than the bundled examples (and on the examples themselves, with --examples).

For each case: mesh the template and the background with Gmsh, write the
exact signed distance of an analytic target at the background vertices,
run `shapematch run` with the stall rule off for 500 iterations (the
reference) and with the defaults, and print
  needed = first iteration within 10% of the best error of the reference,
  stop   = where the default run stopped (reason),
checking needed <= stop <= 2 needed.  Exit 1 when a bound fails.
Usage: bench/stall_cases.py BUILD_DIR [--examples] [--keep DIR]
"""
import csv, json, math, os, subprocess, sys, tempfile

CASES = {
    # 2D, millimetres: a square of side 60 onto a disk of radius 34
    "square-to-disk-2d-mm": dict(
        dim=2, clamp="50,50,6",
        template="""SetFactory("Built-in");
h = 1.5; hc = 2.0;
Point(1) = {20, 20, 0, h}; Point(2) = {80, 20, 0, h};
Point(3) = {80, 80, 0, h}; Point(4) = {20, 80, 0, h};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Physical Curve(1) = {1, 2, 3, 4}; Physical Surface(1) = {1};
""",
        background="""SetFactory("Built-in");
h = 0.8;
Point(1) = {0, 0, 0, h}; Point(2) = {100, 0, 0, h};
Point(3) = {100, 100, 0, h}; Point(4) = {0, 100, 0, h};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Physical Surface(1) = {1};
""",
        sdf=lambda x: math.hypot(x[0] - 50, x[1] - 50) - 34.0),
    # 3D, unit box: a cube of side 0.4 onto a ball of radius 0.24
    "cube-to-ball-3d": dict(
        dim=3, clamp="0.5,0.5,0.5,0.08",
        template="""SetFactory("OpenCASCADE");
Box(1) = {0.3, 0.3, 0.3, 0.4, 0.4, 0.4};
Mesh.MeshSizeMin = 0.035; Mesh.MeshSizeMax = 0.035;
Physical Surface(1) = {1, 2, 3, 4, 5, 6}; Physical Volume(1) = {1};
""",
        background="""SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1, 1, 1};
Mesh.MeshSizeMin = 0.03; Mesh.MeshSizeMax = 0.03;
Physical Volume(1) = {1};
""",
        sdf=lambda x: math.dist(x, (0.5, 0.5, 0.5)) - 0.24),
}


def tidy(dim, src, dst):
    """Gmsh's Medit output with Dimension dim and vertex references 0."""
    lines = open(src).read().split("\n")
    out, i, verts = [], 0, []
    while i < len(lines):
        t = lines[i].strip()
        if t.startswith("Dimension"):
            out.append(" Dimension %d" % dim)
            if t == "Dimension":
                i += 1
        elif t == "Vertices":
            n = int(lines[i + 1])
            out += ["Vertices", str(n)]
            for k in range(n):
                f = lines[i + 2 + k].split()
                verts.append([float(v) for v in f[:dim]])
                out.append(" ".join(f[:dim]) + " 0")
            i += 1 + n
        else:
            out.append(lines[i])
        i += 1
    open(dst, "w").write("\n".join(out))
    return verts


def mesh(dim, geo_text, work, name):
    geo = os.path.join(work, name + ".geo")
    open(geo, "w").write(geo_text)
    raw = os.path.join(work, name + ".gmsh.mesh")
    subprocess.run(["gmsh", "-%d" % dim, geo, "-format", "mesh", "-o", raw, "-v", "1"],
                   check=True, stdout=subprocess.DEVNULL)
    return tidy(dim, raw, os.path.join(work, name + ".mesh"))


def history(path):
    return [float(r["boundary_l2"]) for r in csv.DictReader(open(path))]


def run(build, args, out):
    subprocess.run([os.path.join(build, "shapematch"), "run", "--quiet"] + args + ["-o", out],
                   check=True)
    return json.load(open(os.path.join(out, "summary.json"))), history(
        os.path.join(out, "history.csv"))


def measure(build, name, inputs, clamp, work):
    args = inputs + ["--clamp-ball", clamp]
    ref, h = run(build, args + ["--tol-stall", "0", "--max-iter", "500"],
                 os.path.join(work, name + "-ref"))
    best = min(h)
    needed = next(i for i, v in enumerate(h) if v <= 1.1 * best)
    dflt, _ = run(build, args, os.path.join(work, name + "-default"))
    stop = dflt["iterations"]
    ok = needed <= stop <= 2 * max(needed, 1)
    print("%-22s ref %-15s %3d it, best %.3g | needed %3d | default %-9s %3d it, %.3g (%.2fx) %s"
          % (name, ref["stop_reason"], ref["iterations"], best, needed, dflt["stop_reason"],
             stop, dflt["boundary_l2"], stop / max(needed, 1), "ok" if ok else "OUT OF BOUNDS"))
    sys.stdout.flush()
    return ok


def main():
    build = sys.argv[1]
    keep = sys.argv[sys.argv.index("--keep") + 1] if "--keep" in sys.argv else None
    work = keep or tempfile.mkdtemp(prefix="sm-stall-")
    os.makedirs(work, exist_ok=True)
    ok = True
    if "--examples" in sys.argv:
        root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples")
        for c in ("2d", "3d"):
            d = os.path.join(root, c)
            inputs = ["--template", d + "/template.mesh", "--target-mesh",
                      d + "/background.mesh.gz", "--target-sol", d + "/background.sol.gz"]
            ok &= measure(build, "example-" + c, inputs, open(d + "/clamp").read().strip(), work)
    for name, c in CASES.items():
        dim = c["dim"]
        mesh(dim, c["template"], work, name + "-template")
        bg = mesh(dim, c["background"], work, name + "-background")
        with open(os.path.join(work, name + "-background.sol"), "w") as f:
            f.write("MeshVersionFormatted 2\nDimension %d\nSolAtVertices\n%d\n1 1\n" % (dim, len(bg)))
            f.write("\n".join("%.17g" % c["sdf"](x) for x in bg))
            f.write("\nEnd\n")
        p = os.path.join(work, name)
        inputs = ["--template", p + "-template.mesh", "--target-mesh", p + "-background.mesh",
                  "--target-sol", p + "-background.sol"]
        ok &= measure(build, name, inputs, c["clamp"], work)
    sys.exit(0 if ok else 1)


main()
