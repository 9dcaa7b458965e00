// shapematch example, 3D template: the ball of center (0.5, 0.5, 0.5) and
// radius 0.3, with the clamp ball of radius 0.05 at its center embedded in
// the mesh (OpenCASCADE fragments, so both volumes share the inner sphere).
// References (Medit .mesh):
//   triangles  1  outer sphere                 10  clamp sphere (interior)
//   tetrahedra 1  shell 0.05 < r < 0.3          2  clamp ball r < 0.05
// Sizes as in the paper's 3D example: ~9000 boundary triangles, ~7.3k
// vertices, ~30k tetrahedra (coarser inside).
// Regenerate with examples/generate.sh.
SetFactory("OpenCASCADE");
radius = 0.3;         // template ball
clamp_radius = 0.05;  // clamp ball (use --clamp-ball 0.5,0.5,0.5,0.05)
h_boundary = 0.0175;  // mesh size on the outer sphere
h_interior = 0.06;    // largest mesh size inside
grading = 0.3;        // growth of the size with the depth below the surface
h_clamp = 0.02;       // mesh size on the clamp sphere

Sphere(1) = {0.5, 0.5, 0.5, radius};
Sphere(2) = {0.5, 0.5, 0.5, clamp_radius};
BooleanFragments{ Volume{1}; Delete; }{ Volume{2}; Delete; }
eps = 1e-6;
lo = 0.5 - clamp_radius - eps; hi = 0.5 + clamp_radius + eps;
inner_surfaces() = Surface In BoundingBox{lo, lo, lo, hi, hi, hi};
inner_volumes() = Volume In BoundingBox{lo, lo, lo, hi, hi, hi};
all_surfaces() = Surface{:};
all_volumes() = Volume{:};
outer_surfaces() = all_surfaces();
outer_surfaces() -= inner_surfaces();
outer_volumes() = all_volumes();
outer_volumes() -= inner_volumes();
If (#inner_surfaces() != 1 || #outer_surfaces() != 1 || #inner_volumes() != 1 || #outer_volumes() != 1)
  Error("unexpected fragments: %g/%g surfaces, %g/%g volumes", #inner_surfaces(), #outer_surfaces(), #inner_volumes(), #outer_volumes());
EndIf

Physical Surface(1) = {outer_surfaces()};
Physical Surface(10) = {inner_surfaces()};
Physical Volume(1) = {outer_volumes()};
Physical Volume(2) = {inner_volumes()};

// size: h_boundary at the outer sphere, growing linearly with the depth up
// to h_interior; h_clamp at the clamp sphere, growing away from it
Field[1] = MathEval;
Field[1].F = Sprintf("Min(%g, %g + %g*(%g - Sqrt((x-0.5)^2+(y-0.5)^2+(z-0.5)^2)))", h_interior, h_boundary, grading, radius);
Field[2] = MathEval;
Field[2].F = Sprintf("%g + %g*Abs(Sqrt((x-0.5)^2+(y-0.5)^2+(z-0.5)^2) - %g)", h_clamp, grading, clamp_radius);
Field[3] = Min;
Field[3].FieldsList = {1, 2};
Background Field = 3;

Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
Mesh.Algorithm = 6;              // Frontal-Delaunay (surfaces)
Mesh.Algorithm3D = 1;            // Delaunay (single-threaded, reproducible)
Mesh.SaveElementTagType = 2;     // Medit references = physical tags
General.NumThreads = 1;          // reproducible
