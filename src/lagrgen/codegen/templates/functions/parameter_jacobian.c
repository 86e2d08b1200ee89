    /* out = [0; M⁻¹·P] (2n×n_params) with P = ∂F/∂p − ∂(M·q̈)/∂p, q̈ from the same factor of M
     * as the rhs; the bottom half is written and solved in place. */
#if N_PARAMS && LG_RECURSIVE
    lg_tree w;
    double a[N], *P = out + N * N_PARAMS;
    if (lg_tree_rhs(t, y, y + N, p, u, &w, a))
        return 1;
    lg_parameter_b(t, y, y + N, a, p, u, P);
    lg_tree_solve(&w, P, N_PARAMS, lg_tree_coordinate, P, N_PARAMS, 0);
    memset(out, 0, (size_t)N * N_PARAMS * sizeof(double));
#elif N_PARAMS
    double M[N * N], a[N + N_CONSTRAINTS], *P = out + N * N_PARAMS;
    lg_mf(t, y, y + N, lg_zeros, p, u, M, a);
    if (lg_cholesky(M))
        return 1;
    lg_cholesky_solve(M, a, 1);
#if N_CONSTRAINTS
    /* [M −Aᵀ; A 0]·[δa; δλ] = [P + Hp; Gp] (lg_saddle_columns). */
    double A[NC * N], W[N * NC], S[NC * NC], Hp[N * N_PARAMS], Gp[NC * N_PARAMS];
    if (lg_constrained(t, y, p, u, M, a, a + N, A, W, S))
        return 1;
    lg_parameter_b(t, y, y + N, a, p, u, P);
    lg_constraint_parameter_jacobian(t, y, y + N, a, p, u, Hp, Gp);
    for (int i = 0; i < N * N_PARAMS; ++i)
        P[i] += Hp[i];
    lg_saddle_columns(M, A, W, S, P, Gp, N_PARAMS);
#else
    lg_parameter_b(t, y, y + N, a, p, u, P);
    lg_cholesky_solve(M, P, N_PARAMS);
#endif
    memset(out, 0, (size_t)N * N_PARAMS * sizeof(double));
#else
    (void)t, (void)y, (void)p, (void)u, (void)out;
#endif
    return 0;
