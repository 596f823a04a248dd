/* The factorization and solve of a Newton matrix A = I - mu J (n x n, column-major), written
 * once for the scalar types that need them: driver.c includes this file once per type,
 * with
 *   LU_SCALAR  the type of A, mu and z (double, or double complex for Radau IIA),
 *   LU_ABS     its magnitude (fabs, cabs),
 *   LU_GETF2, LU_GETRS  the LAPACK routines of the type (by_lapack(n): from lapack_from
 *              states, where the library has them),
 *   LU_FACTOR, LU_SOLVE  the names of the two functions it defines.
 * LU_FACTOR returns 1 where A is singular (row swaps in piv: 0-based by the loops,
 * 1-based by LAPACK); LU_SOLVE overwrites z with A^-1 z: the row swaps, then L, then U.
 * Without LU_SCALAR (the file compiled alone) it defines nothing. */
#ifdef LU_SCALAR
int LU_FACTOR(const double *J, LU_SCALAR mu, int n, LU_SCALAR *A, int *piv) {
    int i, j, k;
    for (k = 0; k < n * n; ++k) A[k] = -mu * J[k];
    for (i = 0; i < n; ++i) A[i + i * n] += 1.0;
    if (by_lapack(n)) {
        int info = 0;
        LU_GETF2(&n, &n, A, &n, piv, &info);
        return info != 0;
    }
    for (k = 0; k < n; ++k) {
        int p = k;
        double big = LU_ABS(A[k + k * n]);
        for (i = k + 1; i < n; ++i)
            if (LU_ABS(A[i + k * n]) > big) big = LU_ABS(A[i + k * n]), p = i;
        if (big == 0.0) return 1;
        piv[k] = p;
        if (p != k)
            for (j = 0; j < n; ++j) {
                LU_SCALAR a = A[k + j * n];
                A[k + j * n] = A[p + j * n];
                A[p + j * n] = a;
            }
        for (i = k + 1; i < n; ++i) A[i + k * n] /= A[k + k * n];
        for (j = k + 1; j < n; ++j)
            for (i = k + 1; i < n; ++i) A[i + j * n] -= A[i + k * n] * A[k + j * n];
    }
    return 0;
}

void LU_SOLVE(const LU_SCALAR *A, const int *piv, int n, LU_SCALAR *z) {
    int i, k;
    if (by_lapack(n)) {
        int one = 1, info = 0;
        char trans = 'N';
        LU_GETRS(&trans, &n, &one, (LU_SCALAR *)A, &n, (int *)piv, z, &n, &info);
        return;
    }
    for (k = 0; k < n; ++k)
        if (piv[k] != k) {
            LU_SCALAR a = z[k];
            z[k] = z[piv[k]];
            z[piv[k]] = a;
        }
    for (k = 0; k < n; ++k)
        for (i = k + 1; i < n; ++i) z[i] -= A[i + k * n] * z[k];
    for (k = n - 1; k >= 0; --k) {
        z[k] /= A[k + k * n];
        for (i = 0; i < k; ++i) z[i] -= A[i + k * n] * z[k];
    }
}

#undef LU_SCALAR
#undef LU_ABS
#undef LU_GETF2
#undef LU_GETRS
#undef LU_FACTOR
#undef LU_SOLVE
#endif
