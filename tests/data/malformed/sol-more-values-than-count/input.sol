MeshVersionFormatted 2
Dimension 2
SolAtVertices
2
1 1
0.5
1.5
-2
End
