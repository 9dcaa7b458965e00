// A ball of radius 8.5 mm inside the sphere of radius 10 of sphere.*
// (centre LPS 4, 39, 9): the template the docs match onto the image.
SetFactory("OpenCASCADE");
Sphere(1) = {4, 39, 9, 8.5};
Mesh.MeshSizeMax = 3;
Mesh.MeshSizeFromPoints = 0;
