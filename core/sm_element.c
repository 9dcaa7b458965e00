/* Lame coefficients and the element matrix wrapper of sm_elasticity.h;
 * the kernel itself is inline in sm_element.h. */
#include "sm_elasticity.h"
#include "sm_element.h"

void sm__lame(double young, double poisson, double *lambda, double *mu)
{
    *lambda = young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
    *mu = young / (2.0 * (1.0 + poisson));
}

sm_status sm__elasticity_element_matrix(int dim, const double *vertex_coords,
                                       double lambda, double mu, double alpha,
                                       double *ke, double *volume, sm_error *err)
{
    double vol = 0.0, lmax = 0.0;
    int rc;
    if (dim == 2)
        rc = sm_element_kernel(2, vertex_coords, lambda, mu, alpha, ke, &vol, &lmax);
    else if (dim == 3)
        rc = sm_element_kernel(3, vertex_coords, lambda, mu, alpha, ke, &vol, &lmax);
    else
        return sm_error_set(err, SM_ERR_INVALID, "elasticity: dimension %d is not 2 or 3", dim);
    if (volume)
        *volume = vol;
    if (rc != 0)
        return sm_error_set(err, SM_ERR_NUMERIC,
                            "elasticity: degenerate or non-finite simplex (volume %g, longest edge %g)",
                            vol, lmax);
    return SM_OK;
}
