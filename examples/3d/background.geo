// shapematch example, 3D background: a tetrahedral mesh of the box
// [0,1]^3, finer near the target surface, on which the target's signed
// distance is given (background.sol.gz, computed by examples/tools/sdf).
//
// Target (examples/tools/shapes.h, shape "blob3d"): the star-shaped
// surface r = R(u) around c = (0.5, 0.5, 0.5), u = (x - c)/|x - c|,
//   R(u) = (1 + 0.12 (ux^3 - 3 ux uy^2) + 0.08 (5 uz^3 - 3 uz)/2)
//          / sqrt((ux/0.34)^2 + (uy/0.26)^2 + (uz/0.22)^2),
// a bumpy ellipsoid: three lobes around the z axis, a bulge at the top,
// a dent below.  The size field uses the radial distance |r - R(u)| (an
// upper bound of the Euclidean distance, good enough to grade the mesh).
// Sizes as in the paper's 3D example: ~57k vertices, ~350k tetrahedra.
// Regenerate with examples/generate.sh.
SetFactory("OpenCASCADE");
h_min = 0.009;   // mesh size within dist_min of the target surface
h_max = 0.05;    // mesh size beyond dist_max
dist_min = 0.008;
dist_max = 0.18;

Box(1) = {0, 0, 0, 1, 1, 1};
Physical Volume(1) = {1};

Field[1] = MathEval;
Field[1].F = "Abs(Sqrt((x-0.5)^2+(y-0.5)^2+(z-0.5)^2+1e-12) - (1 + 0.12*((x-0.5)^3 - 3*(x-0.5)*(y-0.5)^2)/((x-0.5)^2+(y-0.5)^2+(z-0.5)^2+1e-12)^1.5 + 0.04*(5*(z-0.5)^3/((x-0.5)^2+(y-0.5)^2+(z-0.5)^2+1e-12)^1.5 - 3*(z-0.5)/Sqrt((x-0.5)^2+(y-0.5)^2+(z-0.5)^2+1e-12))) / Sqrt(((x-0.5)/0.34)^2 + ((y-0.5)/0.26)^2 + ((z-0.5)/0.22)^2 + 1e-12) * Sqrt((x-0.5)^2+(y-0.5)^2+(z-0.5)^2+1e-12))";
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = h_min; Field[2].SizeMax = h_max;
Field[2].DistMin = dist_min; Field[2].DistMax = dist_max;
Background Field = 2;

Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
Mesh.Algorithm = 6;              // Frontal-Delaunay (surfaces)
Mesh.Algorithm3D = 1;            // Delaunay (single-threaded, reproducible)
Mesh.SaveElementTagType = 2;     // Medit references = physical tags
General.NumThreads = 1;          // reproducible
