#if LG_RECURSIVE
#define LG_RHS_WORK 0
    LG_TRY(lg_tree_qdd(t, y, y + N, p, u, out + N));
#else
#define LG_RHS_WORK (N * N + N_CONSTRAINTS * (1 + 2 * N + N_CONSTRAINTS))
    double *M = work;
    LG_TRY(lg_mf(t, y, y + N, lg_zeros, p, u, M, out + N));
    LG_TRY(lg_cholesky(M));
    lg_cholesky_solve(M, out + N, 1);
#if N_CONSTRAINTS
    double *lam = M + N * N, *A = lam + NC, *W = A + NC * N, *S = W + N * NC;
    LG_TRY(lg_constrained(t, y, p, u, M, out + N, lam, A, W, S));
#endif
#endif
    memcpy(out, y + N, N * sizeof(double));
    return 0;
