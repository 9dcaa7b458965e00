// shapematch example, 2D background: a triangle mesh of the box [0,1]^2,
// finer near the target curve, on which the target's signed distance is
// given (background.sol.gz, computed by examples/tools/sdf).
//
// Target (examples/tools/shapes.h, shape "star2d"): the five-lobed star
//   r(theta) = 0.25 (1 + 0.2 cos 5 theta)  around (0.5, 0.5),
// with cos 5 theta written as a polynomial of (cos theta, sin theta).
// The size field uses the radial distance |r - r(theta)| (an upper bound
// of the Euclidean distance, good enough to grade the mesh).
// Regenerate with examples/generate.sh.
SetFactory("Built-in");
h_min = 0.0015;  // mesh size within dist_min of the target curve
h_max = 0.015;   // mesh size beyond dist_max
dist_min = 0.01;
dist_max = 0.15;

Point(1) = {0, 0, 0}; Point(2) = {1, 0, 0}; Point(3) = {1, 1, 0}; Point(4) = {0, 1, 0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Physical Surface(1) = {1};

Field[1] = MathEval;
Field[1].F = "Abs(Sqrt((x-0.5)^2+(y-0.5)^2+1e-12) - 0.25*(1 + 0.2*((x-0.5)^5 - 10*(x-0.5)^3*(y-0.5)^2 + 5*(x-0.5)*(y-0.5)^4)/((x-0.5)^2+(y-0.5)^2+1e-12)^2.5))";
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = h_min; Field[2].SizeMax = h_max;
Field[2].DistMin = dist_min; Field[2].DistMax = dist_max;
Background Field = 2;

Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
Mesh.Algorithm = 6;              // Frontal-Delaunay
Mesh.SaveElementTagType = 2;     // Medit references = physical tags
General.NumThreads = 1;          // reproducible
