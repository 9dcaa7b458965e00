/* How far a match's boundary and its target are from each other, from
 * both sides, and what of the target is missed.
 *
 * The target's surface is taken as samples: the triangles (3D) or
 * segments (2D) of the target surface when the job has one ("surface":
 * the exact distances), otherwise the zero level set of the target field
 * d, extracted by marching tetrahedra (triangles in 2D) on its background
 * mesh ("level-set": exact to that piecewise-linear surface, so as good
 * as the field).  Both sides are measured with the same rule:
 *
 *   samples  every facet of a surface is cut into k^(dim-1) equal parts
 *            (k = ceil(longest edge / spacing)), one sample at each
 *            part's centroid weighted by its measure; the facets' vertices
 *            also count toward the max (weight 0).  The spacing is a
 *            quarter of the mean edge of the template's boundary (with
 *            half, an ellipsoid's faceted target side had its max 20%
 *            low against an independent sampling at 16 parts a facet:
 *            the farthest points lie inside the facets); for the
 *            target's facets, at least a quarter of the target's own mean
 *            edge (a target in other units would otherwise get billions
 *            of samples).  A target that
 *            would get over a million samples (one far larger than the
 *            template: other units) is sampled at a doubled spacing
 *            until it does not, its facets' own sample kept.
 *   result_to_target  distance from the samples of the match's boundary
 *            (the facets that carry the load, see free_boundary) to the
 *            target's surface: exact point-facet distance through a
 *            bounding-volume hierarchy;
 *   target_to_result  distance from the target's samples to the match's
 *            boundary, through a hierarchy over the current boundary.
 *   rms = sqrt(sum w d^2 / sum w), mean = sum w d / sum w, max over the
 *   samples and vertices, p99 the 99th percentile by measure (the
 *   smallest distance within which 99% of the target's area lies).
 *
 * The target_to_result side is what tells a missed protrusion or handle:
 * the result's boundary can lie on the target (result_to_target small)
 * while parts of the target are far from any of it. */
#ifndef SM_COVERAGE_H
#define SM_COVERAGE_H

#include <stdint.h>

#include "sm_error.h"
#include "sm_field.h"
#include "sm_mesh.h"
#include "sm_surface.h"

typedef enum sm_distance_method {
    SM_DISTANCE_NONE = 0,      /* not measured (a cancel before the run) */
    SM_DISTANCE_SURFACE = 1,   /* to the target surface's own facets */
    SM_DISTANCE_LEVEL_SET = 2  /* to the zero level set of the target field */
} sm_distance_method;
/* "surface", "level-set"; NULL for SM_DISTANCE_NONE. */
const char *sm_distance_method_name(sm_distance_method m);

typedef struct sm_distance_side {
    double rms, max, mean;
    double p99;                /* 99th percentile by measure */
} sm_distance_side;

typedef struct sm_distance {
    sm_distance_method method;
    sm_distance_side result_to_target; /* from the match's boundary */
    sm_distance_side target_to_result; /* from the target's surface */
} sm_distance;

typedef struct sm_coverage sm_coverage;

/* The target side: its surface, the count and measure of its samples
 * and the descent's thinned samples (the samples themselves and the
 * target's hierarchy are made by sm_coverage_measure, which alone reads
 * them).  It opens no parallel region: it may run beside other work
 * (proto/job builds it beside the elastic set-up).  target is the
 * field (its zero level set is used when surface is NULL); surface, when
 * given, is the target's exact surface (borrowed, must outlive the
 * coverage).  m is the
 * template with its boundary built (sm_mesh_build_boundary): its active
 * facets (boundary references not in free_refs) are the boundary
 * measured, and its boundary's mean edge sets the spacing.  Errors:
 * SM_ERR_INVALID when the level set is empty (d does not change sign on
 * the background) or the dimensions differ, SM_ERR_NOMEM. */
sm_status sm_coverage_new(const sm_field *target, const sm_surface *surface, const sm_mesh *m,
                          const int32_t *free_refs, int nfree, sm_coverage **out,
                          sm_error *err);
void sm_coverage_free(sm_coverage *c);

sm_distance_method sm_coverage_method(const sm_coverage *c);
/* Number of target samples and their total measure (area 3D, length 2D). */
int64_t sm_coverage_target_samples(const sm_coverage *c, double *measure);

/* Both sides for the boundary of m (the mesh given to sm_coverage_new) at
 * vertex positions coords (nverts * dim).  Keeps each target sample's
 * distance for sm_coverage_missed.  SM_ERR_NOMEM. */
sm_status sm_coverage_measure(sm_coverage *c, const double *coords, sm_distance *out,
                              sm_error *err);

/* The part of the target farther than threshold from the boundary of the
 * last sm_coverage_measure (result_side 0), or the part of that boundary
 * farther than threshold from the target (result_side 1: what the result
 * has that the target has not, such as a sheet across a handle's hole):
 * its share of the side's measure, its largest distance, and its box and
 * centre (weighted by measure).  All zero before a measure. */
typedef struct sm_coverage_missed {
    double fraction;           /* 0..1 of the target's measure */
    double measure;            /* area (3D) or length (2D) missed */
    double max;                /* farthest missed sample */
    double lo[3], hi[3];       /* box of the missed samples (z = 0 in 2D) */
    double centre[3];
    int64_t samples;
} sm_coverage_missed;
void sm_coverage_missed_part(const sm_coverage *c, int result_side, double threshold,
                             sm_coverage_missed *out);

/* Topology of the target surface and of the template's boundary, when it
 * can be told: the number of connected pieces and, for closed surfaces
 * (3D), the genus from the Euler characteristic (pieces - chi/2).  A
 * deformation keeps both, so a difference means a target no match can
 * cover (a handle, a torus, a hole). */
typedef struct sm_coverage_topology {
    int known;                 /* 1 when both surfaces are closed */
    int64_t target_pieces, template_pieces;
    int64_t target_genus, template_genus; /* 3D; 0 in 2D */
    int64_t target_chi, template_chi;
} sm_coverage_topology;
void sm_coverage_get_topology(const sm_coverage *c, sm_coverage_topology *out);

#endif
