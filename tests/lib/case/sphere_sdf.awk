# Signed distance to the circle (sphere) of radius R (awk -v R=...)
# centred at the origin, at the vertices of a Medit mesh, as a scalar
# .sol on stdout: the analytic target of the test cases.
{ for (i = 1; i <= NF; i++) tok[++n] = $i }
END {
    for (k = 1; k <= n; k++) {
        if (tok[k] == "Dimension") dim = tok[++k] + 0
        else if (tok[k] == "Vertices") { nv = tok[++k] + 0; start = k; break }
    }
    flat = 1
    for (v = 0; v < nv; v++) {
        b = start + v * (dim + 1)
        x[v] = tok[b + 1] + 0; y[v] = tok[b + 2] + 0; z[v] = dim == 3 ? tok[b + 3] + 0 : 0
        if (z[v] != 0) flat = 0
    }
    sdim = (dim == 3 && !flat) ? 3 : 2
    printf "MeshVersionFormatted 2\n\nDimension %d\n\nSolAtVertices\n%d\n1 1\n", sdim, nv
    for (v = 0; v < nv; v++)
        printf "%.17g\n", sqrt(x[v]^2 + y[v]^2 + (sdim == 3 ? z[v]^2 : 0)) - R
    printf "\nEnd\n"
}
