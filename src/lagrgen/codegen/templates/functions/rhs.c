#if LG_RECURSIVE
    if (lg_tree_qdd(t, y, y + N, p, u, out + N))
        return 1;
#else
    double M[N * N];
    lg_mf(t, y, y + N, lg_zeros, p, u, M, out + N);
    if (lg_cholesky(M))
        return 1;
    lg_cholesky_solve(M, out + N, 1);
#if N_CONSTRAINTS
    double lam[NC], A[NC * N], W[N * NC], S[NC * NC];
    if (lg_constrained(t, y, p, u, M, out + N, lam, A, W, S))
        return 1;
#endif
#endif
    memcpy(out, y + N, N * sizeof(double));
    return 0;
