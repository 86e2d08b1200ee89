    /* out = [0; M⁻¹·P] (2n×n_params) with P = ∂F/∂p − ∂(M·q̈)/∂p, q̈ from the same factor of M
     * as the rhs; the bottom half is written and solved in place. */
#if N_PARAMS && LG_RECURSIVE
#define LG_PARAMETER_JACOBIAN_WORK 0
    return lg_tree_parameter_jacobian(t, y, p, u, out);
#elif N_PARAMS
#define LG_PARAMETER_JACOBIAN_WORK                                                                \
    (N * N + N + N_CONSTRAINTS * (1 + 2 * N + N_CONSTRAINTS)                                      \
     + (N_CONSTRAINTS ? (N + N_CONSTRAINTS) * N_PARAMS : 0))
    double *M = work, *a = M + N * N, *P = out + N * N_PARAMS;
    LG_TRY(lg_mf(t, y, y + N, lg_zeros, p, u, M, a));
    LG_TRY(lg_cholesky(M));
    lg_cholesky_solve(M, a, 1);
#if N_CONSTRAINTS
    /* [M −Aᵀ; A 0]·[δa; δλ] = [P + Hp; Gp] (lg_saddle_columns). */
    double *A = a + N + NC, *W = A + NC * N, *S = W + N * NC, *Hp = S + NC * NC;
    double *Gp = Hp + N * N_PARAMS;
    LG_TRY(lg_constrained(t, y, p, u, M, a, a + N, A, W, S));
    LG_TRY(lg_parameter_b(t, y, y + N, a, p, u, P));
    LG_TRY(lg_constraint_parameter_jacobian(t, y, y + N, a, p, u, Hp, Gp));
    for (int i = 0; i < N * N_PARAMS; ++i)
        P[i] += Hp[i];
    lg_saddle_columns(M, A, W, S, P, Gp, N_PARAMS);
#else
    LG_TRY(lg_parameter_b(t, y, y + N, a, p, u, P));
    lg_cholesky_solve(M, P, N_PARAMS);
#endif
    memset(out, 0, (size_t)N * N_PARAMS * sizeof(double));
#else
#define LG_PARAMETER_JACOBIAN_WORK 0
    (void)t, (void)y, (void)p, (void)u, (void)out;
#endif
    return 0;
