MeshVersionFormatted 2
Dimension 2
SolAtVertices
3
1 3
0.5
1.5
-2
End
