SetFactory("OpenCASCADE");
Disk(1) = {0, 0, 0, 0.5};
Mesh.CharacteristicLengthMax = 0.08;
