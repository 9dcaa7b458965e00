// A ball of radius 0.3 in a shell of radius 0.8 with physical names:
// volumes "core" (1) and "shell" (2), the outer surface "skin" (3).
// tests/cli/clamp_names.sh and tests/integration/option_walk.sh.
SetFactory("OpenCASCADE");
Sphere(1) = {0, 0, 0, 0.8};
Sphere(2) = {0, 0, 0, 0.3};
BooleanFragments{ Volume{1}; Delete; }{ Volume{2}; Delete; }
Physical Volume("core", 1) = {2};
Physical Volume("shell", 2) = {3};
Physical Surface("skin", 3) = {3};
Mesh.MeshSizeMax = 0.3;
