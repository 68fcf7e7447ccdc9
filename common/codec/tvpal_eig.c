/* tvpal_eig.c: LAPACK dsyev behind a small C interface (see tvpal_eig.h).
 * Only this file knows LAPACK's Fortran calling convention. */
#include "tvpal_eig.h"
#include "tvpal_dct.h"
#include "tvpal_error.h"

#include <math.h>
#include <string.h>

#ifdef HAVE_LAPACK
extern void dsyev_(const char *jobz, const char *uplo, const int *n, double *a,
                   const int *lda, double *w, double *work, const int *lwork,
                   int *info);
#endif

int tvpal_eig_available(void)
{
#ifdef HAVE_LAPACK
    return 1;
#else
    return 0;
#endif
}

int tvpal_eig_sym(int n, double *a, double *w)
{
#ifdef HAVE_LAPACK
    double work[TVPAL_NMAX * TVPAL_NMAX * 4], ev[TVPAL_NMAX],
        vec[TVPAL_NMAX * TVPAL_NMAX];
    int lwork = (int)(sizeof work / sizeof *work), info = 0;
    if (n < 1 || n > TVPAL_NMAX)
        return TVPAL_E_INVAL;
    /* Row-major symmetric = column-major symmetric: pass as is; on return
     * column k of the column-major array (= row k here) is eigenvector k. */
    dsyev_("V", "U", &n, a, &n, ev, work, &lwork, &info);
    if (info != 0)
        return TVPAL_E_INVAL;
    /* Ascending -> descending; fix signs. */
    for (int k = 0; k < n; k++) {
        const double *src = a + (size_t)(n - 1 - k) * n;
        int big = 0;
        for (int j = 1; j < n; j++)
            if (fabs(src[j]) > fabs(src[big]))
                big = j;
        double sgn = src[big] < 0 ? -1.0 : 1.0;
        for (int j = 0; j < n; j++)
            vec[k * n + j] = sgn * src[j];
        w[k] = ev[n - 1 - k];
    }
    memcpy(a, vec, sizeof(double) * (size_t)n * n);
    return 0;
#else
    (void)n;
    (void)a;
    (void)w;
    return TVPAL_E_SYS;
#endif
}
