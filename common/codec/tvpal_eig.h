/* tvpal_eig.h: symmetric eigendecomposition (LAPACK dsyev) for the KLT. */
#ifndef TVPAL_EIG_H
#define TVPAL_EIG_H

/* Eigenvalues (descending) into w[n] and eigenvectors into the rows of
 * a[n*n] (a holds the symmetric matrix on entry, row-major).  Each
 * eigenvector's largest-magnitude component is made positive, so the
 * result is deterministic.  n <= 16.  Returns 0, TVPAL_E_SYS when built
 * without LAPACK, or TVPAL_E_INVAL when LAPACK fails to converge. */
int tvpal_eig_sym(int n, double *a, double *w);

/* Whether tvpal_eig_sym works in this build. */
int tvpal_eig_available(void);

#endif
