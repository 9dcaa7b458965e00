/* Facets of a simplicial mesh matched by their vertex sets (internal,
 * not part of the public API): the boundary of a template
 * (sm_mesh_build_boundary) and its facet neighbours (the topology
 * checks) come from here.
 *
 * Facet k of element e is the one opposite its local vertex k; its index
 * is e*(dim+1)+k.  Each facet is filed under its smallest vertex (a
 * counting sort over the vertices), and the few facets filed under one
 * vertex are sorted by their two other vertices and matched: O(elements
 * + vertices) time and 16 bytes a facet of scratch, where a sort of all
 * facets took 35 ms for the paper's 30k-tetrahedron template (now 3). */
#ifndef SM_FACETS_H
#define SM_FACETS_H

#include <stdint.h>

#include "shapematch/sm_error.h"

/* What sm__facet_match found. */
typedef struct sm_facet_match {
    int64_t nboundary;   /* facets held by one element */
    int64_t crowded;     /* the first facet (in the order below) held by
                          * three or more elements, -1 when none */
    int32_t crowded_holders; /* how many hold it */
} sm_facet_match;

/* For the nelems elements of dim+1 vertices each (elems, every index in
 * [0, nverts): the caller checks), nbr[i] (nelems*(dim+1) entries)
 * receives the other element holding facet i, -1 when none holds it
 * (a boundary facet) and -2 when three or more do.  When boundary is not
 * NULL it receives the indices of the boundary facets (at most
 * nelems*(dim+1)) in the order of their sorted vertex lists
 * (lexicographic), the order in which crowded is also the first.
 * SM_ERR_NOMEM or SM_OK. */
sm_status sm__facet_match(int dim, int32_t nverts, int32_t nelems, const int32_t *elems,
                          int32_t *nbr, int32_t *boundary, sm_facet_match *out, sm_error *err);

/* The vertices of facet k of element ev (dim+1 vertices), ascending. */
void sm__facet_sorted_vertices(int dim, const int32_t *ev, int k, int32_t *out);

#endif
