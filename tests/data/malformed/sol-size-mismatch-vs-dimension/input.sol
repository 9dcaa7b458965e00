MeshVersionFormatted 2
Dimension 3
SolAtVertices
3
1 2
1 2
3 4
5 6
End
