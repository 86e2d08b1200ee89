#if N_CONSTRAINTS
    /* out = [A (NC×N), λ (NC), H = ∂(Aᵀλ)/∂q (N×N)], λ from the constrained solve at (q, q̇). */
    double M[N * N], a[N + NC], W[N * NC], S[NC * NC], G[NC * 2 * N];
    lg_mf(t, y, y + N, lg_zeros, p, u, M, a);
    if (lg_cholesky(M))
        return 1;
    lg_cholesky_solve(M, a, 1);
    if (lg_constrained(t, y, p, u, M, a, a + N, out, W, S))
        return 1;
    memcpy(out + NC * N, a + N, NC * sizeof(double));
    lg_constraint_jacobian(t, y, y + N, a, p, u, out + NC * N + NC, G);
#else
    (void)t, (void)y, (void)p, (void)u;
    memset(out, 0, (size_t)N * N * sizeof(double));
#endif
    return 0;
