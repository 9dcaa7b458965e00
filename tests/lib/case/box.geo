SetFactory("OpenCASCADE");
Rectangle(1) = {-1.5, -1.5, 0, 3, 3};
Mesh.CharacteristicLengthMax = 0.1;
