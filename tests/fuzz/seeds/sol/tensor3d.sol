MeshVersionFormatted 2
Dimension 3
SolAtVertices
2
1 3
1 2 3 4 5 6
-1 0.5 2 0 0 7
End
