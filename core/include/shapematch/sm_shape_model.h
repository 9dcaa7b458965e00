/* A statistical shape model of N shapes in correspondence: N copies of
 * one point set (the vertices of one template matched onto N targets, so
 * point p of every shape is the same material point), Procrustes-aligned,
 * their mean, the principal modes of their variation and the measures
 * ShapeWorks reports for a model (compactness, generalization,
 * specificity).
 *
 * Shapes are given as N arrays of npoints*dim coordinates (x0 y0 [z0] x1
 * ...), dim 2 or 3.  In the formulas below a shape is the vector x of
 * P = npoints*dim numbers, and the distance between two shapes a, b is
 * the mean over the points of the Euclidean distance between a point of
 * a and the same point of b (ShapeWorks' particle distance):
 *   dist(a, b) = (1/npoints) sum_p |a_p - b_p|.
 *
 * Alignment (generalized Procrustes analysis): each shape is moved onto
 * a reference by the transform that minimizes the sum of squared point
 * distances (Kabsch/Umeyama through the SVD of the dim x dim
 * cross-covariance, reflections excluded); rigid = rotation +
 * translation, similarity = also a uniform scale, none = the shapes as
 * given.  The reference starts as the first shape and becomes the mean
 * of the aligned shapes until the mean moves by less than 1e-12 of its
 * size (at most SM_SHAPE_MODEL_MAX_GPA rounds); with similarity, the
 * mean is rescaled each round to the centroid size of the first shape
 * (otherwise the scales shrink together towards 0).  Finally the mean is
 * moved rigidly onto the first shape and every shape aligned onto it
 * once more, so the model lives in the first shape's frame: a rigid
 * motion of any other shape changes nothing but rounding.
 *
 * PCA: X is the N x P matrix of aligned shapes minus their mean; the
 * N x N Gram matrix G = X X^T (BLAS dsyrk) gives the eigenpairs
 * (LAPACK dsyevr) G v_k = g_k v_k, g_1 >= g_2 >= ...; mode k is the unit
 * vector u_k = X^T v_k / sqrt(g_k), its variance lambda_k = g_k / (N-1),
 * and shape i's score on it is X_i . u_k = sqrt(g_k) v_ik.  A mode is
 * kept when g_k > 1e-12 g_1 (at most N-1 modes).  Memory: the N aligned
 * shapes, the kept modes (at most N-1 shapes' worth) and N^2 numbers;
 * time: N^2 P / 2 for G, N^3 for its eigenpairs, N K P for the modes.
 *
 * Measures, for M = 1 .. neval modes (curves, as ShapeWorks plots them):
 *   variance_explained[k] = lambda_k / sum of all lambda;
 *   compactness[M-1]    = sum_{k<=M} lambda_k / sum of all lambda;
 *   generalization[M-1] = mean over held-out shapes i of
 *       dist(x_i, reconstruction of x_i by the model of the other N-1
 *       shapes with its first M modes): leave-one-out, each held-out
 *       model a PCA of the others' scores (exact: every shape lies in the
 *       span of the kept modes); at most eval_shapes held-out shapes,
 *       evenly spaced over 0..N-1 (all when N <= eval_shapes);
 *   specificity[M-1]    = mean over `samples` random shapes
 *       s = mean + sum_{k<=M} b_k u_k, b_k ~ Normal(0, lambda_k), of
 *       dist(s, the training shape nearest to s in the Euclidean norm of
 *       R^P); each sample draws its neval scores once and its shape with
 *       M modes takes the first M (the curves share their draws); the
 *       normal numbers come from a xorshift64* generator seeded with
 *       `seed` and Box-Muller, so a model's figures are repeatable.
 * Generalization and specificity need N >= 3 and N >= 2 (else 0). */
#ifndef SM_SHAPE_MODEL_H
#define SM_SHAPE_MODEL_H

#include <stddef.h>
#include <stdint.h>

#include "sm_error.h"

#define SM_SHAPE_MODEL_MAX_GPA 100
#define SM_SHAPE_MODEL_EVAL_MODES 10     /* default neval (at most the modes) */
#define SM_SHAPE_MODEL_EVAL_SHAPES 32    /* default held-out shapes */
#define SM_SHAPE_MODEL_SAMPLES 1000      /* default specificity samples */
#define SM_SHAPE_MODEL_SEED 20261203u    /* default seed */

typedef enum sm_shape_align {
    SM_SHAPE_ALIGN_NONE = 0,
    SM_SHAPE_ALIGN_RIGID = 1,
    SM_SHAPE_ALIGN_SIMILARITY = 2
} sm_shape_align;
/* "none", "rigid", "similarity"; sm_shape_align_parse: 0 or -1. */
const char *sm_shape_align_name(sm_shape_align a);
int sm_shape_align_parse(const char *name, sm_shape_align *out);

typedef struct sm_shape_model_opts {
    sm_shape_align align;
    int eval_modes;      /* curves up to this many modes; 0: the default */
    int eval_shapes;     /* generalization's held-out shapes; 0: default */
    int samples;         /* specificity's samples; 0: default */
    uint64_t seed;       /* 0: SM_SHAPE_MODEL_SEED */
} sm_shape_model_opts;

typedef struct sm_shape_model {
    int dim, nshapes, nmodes;
    int64_t npoints;
    size_t nvalues;          /* P = npoints * dim */
    double *centered;        /* nshapes * P: shape i after alignment, minus
                              * the mean (row i of X) */
    double *transforms;      /* nshapes * 13: scale, R (3x3 row-major, dim x dim
                              * used), t (3): aligned = scale R x + t */
    double *mean;            /* P */
    double *modes;           /* nmodes * P, unit vectors, mode k at k*P */
    double *variance;        /* nmodes: lambda_k */
    double total_variance;   /* sum of all lambda (trace of G / (N-1)) */
    double *scores;          /* nshapes * nmodes, row i = shape i */
    int gpa_rounds;          /* Procrustes rounds taken (0 for none) */
    int neval, eval_shapes, samples;
    uint64_t seed;
    double *compactness, *generalization, *specificity; /* neval each */
} sm_shape_model;

/* Builds the model of shapes[0..nshapes-1] (each npoints*dim finite
 * coordinates; nshapes >= 1, dim 2 or 3; opts NULL: rigid and the
 * defaults).  SM_ERR_INVALID on bad sizes or non-finite coordinates,
 * SM_ERR_NOMEM, SM_ERR_NUMERIC when LAPACK fails.  Free with
 * sm_shape_model_free. */
sm_status sm_shape_model_build(const double *const *shapes, int nshapes, int64_t npoints,
                               int dim, const sm_shape_model_opts *opts,
                               sm_shape_model **out, sm_error *err);
void sm_shape_model_free(sm_shape_model *m);

/* The shape mean + sum_k b[k] sqrt(lambda_k) u_k (b in standard
 * deviations, nb <= nmodes) into out (P values). */
void sm_shape_model_instance(const sm_shape_model *m, const double *b, int nb, double *out);

/* Moves x (npoints*dim, in place) by the similarity (scale, R, t) that
 * best maps it onto ref (least squares; kind rigid: scale 1; none:
 * identity) and stores the transform as 13 numbers when t13 is set. */
void sm_shape_align_onto(double *x, const double *ref, int64_t npoints, int dim,
                         sm_shape_align kind, double *t13);

#endif
