SetFactory("OpenCASCADE"); Box(1)={0,0,0,1,1,1}; Mesh.MeshSizeMax=0.5; Mesh.MeshSizeMin=0.5; Physical Volume(2)={1}; Physical Surface(5)={1,2,3,4,5,6};
