#if N_CONSTRAINTS
    /* out = [A (NC×N), λ (NC), H = ∂(Aᵀλ)/∂q (N×N)], λ from the constrained solve at (q, q̇). */
#define LG_CONSTRAINT_TERMS_WORK (N * N + N + NC + N * NC + NC * NC + NC * 2 * N)
    double *M = work, *a = M + N * N, *W = a + N + NC, *S = W + N * NC, *G = S + NC * NC;
    LG_TRY(lg_mf(t, y, y + N, lg_zeros, p, u, M, a));
    LG_TRY(lg_cholesky(M));
    lg_cholesky_solve(M, a, 1);
    LG_TRY(lg_constrained(t, y, p, u, M, a, a + N, out, W, S));
    memcpy(out + NC * N, a + N, NC * sizeof(double));
    return lg_constraint_jacobian(t, y, y + N, a, p, u, out + NC * N + NC, G);
#else
#define LG_CONSTRAINT_TERMS_WORK 0
    (void)t, (void)y, (void)p, (void)u;
    memset(out, 0, (size_t)N * N * sizeof(double));
    return 0;
#endif
