SetFactory("OpenCASCADE");
Sphere(1) = {0, 0, 0, 0.8};
Mesh.MeshSizeFromPoints = 0;
