SetFactory("OpenCASCADE");
Box(1) = {-1, -1, -1, 2, 2, 2};
Mesh.CharacteristicLengthMax = 0.5;
