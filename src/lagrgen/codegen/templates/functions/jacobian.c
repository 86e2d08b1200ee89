    /* The bottom half of out is B = [∂F/∂q − ∂(M·q̈)/∂q | ∂F/∂q̇] (n×2n, rows of length 2n like
     * out's), overwritten in place by M⁻¹·B with the factor of M the rhs's q̈ came from. */
#if LG_RECURSIVE
#define LG_JACOBIAN_WORK 0
    return lg_tree_jacobian(t, y, p, u, out);
#else
#define LG_JACOBIAN_WORK                                                                          \
    (N * N + N + N_CONSTRAINTS * (1 + 2 * N + N_CONSTRAINTS)                                      \
     + (N_CONSTRAINTS ? N * N + 2 * N_CONSTRAINTS * N : 0))
    double *M = work, *a = M + N * N, *B = out + 2 * N * N;
    LG_TRY(lg_mf(t, y, y + N, lg_zeros, p, u, M, a));
    LG_TRY(lg_cholesky(M));
    lg_cholesky_solve(M, a, 1);
#if N_CONSTRAINTS
    /* [M −Aᵀ; A 0]·[δa; δλ] = [R1; R2] with R1 = B + H·δq, R2 = G: δλ = S⁻¹(R2 − A·M⁻¹R1),
     * δa = M⁻¹R1 + W·δλ. */
    double *A = a + N + NC, *W = A + NC * N, *S = W + N * NC, *H = S + NC * NC, *G = H + N * N;
    LG_TRY(lg_constrained(t, y, p, u, M, a, a + N, A, W, S));
    LG_TRY(lg_jacobian_b(t, y, y + N, a, p, u, B));
    LG_TRY(lg_constraint_jacobian(t, y, y + N, a, p, u, H, G));
    for (int i = 0; i < N; ++i)
        for (int j = 0; j < N; ++j)
            B[i * 2 * N + j] += H[i * N + j];
    lg_saddle_columns(M, A, W, S, B, G, 2 * N);
#else
    LG_TRY(lg_jacobian_b(t, y, y + N, a, p, u, B));
    lg_cholesky_solve(M, B, 2 * N);
#endif
    memset(out, 0, (size_t)2 * N * N * sizeof(double));
    for (int i = 0; i < N; ++i)
        out[i * 2 * N + N + i] = 1.0;
    return 0;
#endif
