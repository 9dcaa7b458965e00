MeshVersionFormatted 2
Dimension 2
Vertices
4
           0            0            1
           1            0            1
           1            1            1
           0            1            1
Edges
4
     1      2      1
     2      3      1
     3      4      1
     4      1      1
Triangles
2
     1      2      3      0
     1      3      4      0
End
