    /* out = [ẏ; then per direction s: J·dy_s + ∂ẏ/∂p·dp_s]. Recursive formulation: tangent sweeps
     * of the recursion over the tree (lg_tree_directions). Dense: M, F (and A, γ) are evaluated once,
     * with the tape c of their forward-mode coefficients (kernel motion_tape); each direction then
     * runs the tangent program (motion_tangent: δR = δF − δM·q̈ + δAᵀ·λ, δG = δγ − δA·q̈) and
     * solves M·δq̈ = δR with the rhs's factor of M (or the saddle point [M −Aᵀ; A 0]). */
#if LG_RECURSIVE
#define LG_DIRECTIONAL_DERIVATIVES_WORK 0
    return lg_tree_directions(t, y, p, u, k, dy, dp, out);
#else
    /* The tape c, M, a = [q̈, λ], A, W, S, then LG_LANES directions' D, P, R and G. */
#define LG_DIRECTIONAL_DERIVATIVES_WORK                                                           \
    (LG_MOTION_TAPE_C + N * N + N + N_CONSTRAINTS * (1 + 2 * N + N_CONSTRAINTS)                   \
     + (3 * N + N_PARAMS + N_CONSTRAINTS) * LG_LANES + 2)
    double *c = work, *M = c + LG_MOTION_TAPE_C, *a = M + N * N, *A = a + N + N_CONSTRAINTS;
    double *W = A + N_CONSTRAINTS * N, *S = W + N * N_CONSTRAINTS;
    double *D = S + N_CONSTRAINTS * N_CONSTRAINTS, *P = D + 2 * N * LG_LANES;
    double *R = P + N_PARAMS * LG_LANES + 1, *G = R + N * LG_LANES;
    LG_TRY(lg_motion_tape(t, y, y + N, lg_zeros, p, u, M, a, A, a + N, c));
    LG_TRY(lg_cholesky(M));
    lg_cholesky_solve(M, a, 1);
#if N_CONSTRAINTS
    LG_TRY(lg_constrained_solve(M, a, a + N, A, W, S));
#else
    (void)W, (void)S;
#endif
    memcpy(out, y + N, N * sizeof(double));
    memcpy(out + N, a, N * sizeof(double));
    /* LG_LANES directions at a time: their tangents in lanes (entry i of direction b at
     * [i·LG_LANES + b]), then one solve with the LG_LANES columns R (missing ones zero) */
    for (int s0 = 0; s0 < k; s0 += LG_LANES) {
        const int width = k - s0 < LG_LANES ? k - s0 : LG_LANES;
        for (int b = 0; b < LG_LANES; ++b) {
            const double *ds = dy + (size_t)2 * N * (s0 + b);
            const double *ps = dp + (size_t)N_PARAMS * (s0 + b);
            for (int i = 0; i < 2 * N; ++i)
                D[i * LG_LANES + b] = b < width ? ds[i] : 0.0;
            for (int j = 0; j < N_PARAMS; ++j)
                P[j * LG_LANES + b] = b < width ? ps[j] : 0.0;
        }
        LG_TRY(lg_motion_tangent(c, a, D, D + N * LG_LANES, P, R, G));
#if N_CONSTRAINTS
        lg_saddle_columns(M, A, W, S, R, G, LG_LANES);
#else
        lg_cholesky_solve(M, R, LG_LANES);
#endif
        for (int b = 0; b < width; ++b) {
            double *o = out + (size_t)2 * N * (s0 + b + 1);
            memcpy(o, dy + (size_t)2 * N * (s0 + b) + N, N * sizeof(double));
            for (int i = 0; i < N; ++i)
                o[N + i] = R[i * LG_LANES + b];
        }
    }
    return 0;
#endif
