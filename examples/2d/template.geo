// shapematch example, 2D template: the disk of center (0.5, 0.5) and radius
// 0.25, with the clamp disk of radius 0.04 at its center embedded in the
// mesh.  References (Medit .mesh):
//   edges     1  outer boundary circle        10  clamp circle (interior)
//   triangles 1  annulus 0.04 < r < 0.25       2  clamp disk r < 0.04
// About 1200 mesh edges in all (the paper's 2D template), finer at the
// outer boundary.  Regenerate with examples/generate.sh.
SetFactory("Built-in");
xc = 0.5; yc = 0.5;
radius = 0.25;        // template disk
clamp_radius = 0.04;  // clamp disk (use --clamp-ball 0.5,0.5,0.04)
h_boundary = 0.016;   // mesh size on the outer circle
h_clamp = 0.02;       // mesh size on the clamp circle
h_interior = 0.05;    // mesh size far from both circles

Point(1) = {xc, yc, 0};
Point(2) = {xc + radius, yc, 0};
Point(3) = {xc, yc + radius, 0};
Point(4) = {xc - radius, yc, 0};
Point(5) = {xc, yc - radius, 0};
Point(6) = {xc + clamp_radius, yc, 0};
Point(7) = {xc, yc + clamp_radius, 0};
Point(8) = {xc - clamp_radius, yc, 0};
Point(9) = {xc, yc - clamp_radius, 0};
Circle(1) = {2, 1, 3}; Circle(2) = {3, 1, 4}; Circle(3) = {4, 1, 5}; Circle(4) = {5, 1, 2};
Circle(5) = {6, 1, 7}; Circle(6) = {7, 1, 8}; Circle(7) = {8, 1, 9}; Circle(8) = {9, 1, 6};
Curve Loop(1) = {1, 2, 3, 4};
Curve Loop(2) = {5, 6, 7, 8};
Plane Surface(1) = {1, 2};   // annulus
Plane Surface(2) = {2};      // clamp disk

Physical Curve(1) = {1, 2, 3, 4};
Physical Curve(10) = {5, 6, 7, 8};
Physical Surface(1) = {1};
Physical Surface(2) = {2};

// size: h_boundary on the outer circle growing to h_interior at depth
// 0.15, h_clamp on the clamp circle growing to h_interior at 0.08
Field[1] = Distance;
Field[1].CurvesList = {1, 2, 3, 4};
Field[1].NumPointsPerCurve = 400;
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = h_boundary; Field[2].SizeMax = h_interior;
Field[2].DistMin = 0.0; Field[2].DistMax = 0.15;
Field[3] = Distance;
Field[3].CurvesList = {5, 6, 7, 8};
Field[3].NumPointsPerCurve = 100;
Field[4] = Threshold;
Field[4].InField = 3;
Field[4].SizeMin = h_clamp; Field[4].SizeMax = h_interior;
Field[4].DistMin = 0.0; Field[4].DistMax = 0.08;
Field[5] = Min;
Field[5].FieldsList = {2, 4};
Background Field = 5;

Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
Mesh.Algorithm = 6;              // Frontal-Delaunay
Mesh.SaveElementTagType = 2;     // Medit references = physical tags
General.NumThreads = 1;          // reproducible
