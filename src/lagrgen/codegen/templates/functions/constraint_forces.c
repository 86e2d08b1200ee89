#if N_CONSTRAINTS
    double M[N * N], a[N], A[NC * N], W[N * NC], S[NC * NC];
    lg_mf(t, y, y + N, lg_zeros, p, u, M, a);
    if (lg_cholesky(M))
        return 1;
    lg_cholesky_solve(M, a, 1);
    return lg_constrained(t, y, p, u, M, a, out, A, W, S);
#else
    (void)t, (void)y, (void)p, (void)u, (void)out;
    return 0;
#endif
