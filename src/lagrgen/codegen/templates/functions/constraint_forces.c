#if N_CONSTRAINTS
#define LG_CONSTRAINT_FORCES_WORK (N * N + N + 2 * NC * N + NC * NC)
    double *M = work, *a = M + N * N, *A = a + N, *W = A + NC * N, *S = W + N * NC;
    LG_TRY(lg_mf(t, y, y + N, lg_zeros, p, u, M, a));
    LG_TRY(lg_cholesky(M));
    lg_cholesky_solve(M, a, 1);
    return lg_constrained(t, y, p, u, M, a, out, A, W, S);
#else
#define LG_CONSTRAINT_FORCES_WORK 0
    (void)t, (void)y, (void)p, (void)u, (void)out;
    return 0;
#endif
