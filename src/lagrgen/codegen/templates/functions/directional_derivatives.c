    /* out = [ẏ; then per direction s: J·dy_s + ∂ẏ/∂p·dp_s]. Recursive formulation: tangent sweeps
     * of the recursion over the tree (lg_tree_directions). Dense: M, F (and A, γ) are evaluated once,
     * with the tape c of their forward-mode coefficients (kernel motion_tape); each direction then
     * runs the tangent program (motion_tangent: δR = δF − δM·q̈ + δAᵀ·λ, δG = δγ − δA·q̈) and
     * solves M·δq̈ = δR with the rhs's factor of M (or the saddle point [M −Aᵀ; A 0]). */
#if LG_RECURSIVE
    return lg_tree_directions(t, y, p, u, k, dy, dp, out);
#else
#if LG_MOTION_TAPE_C > LG_TAPE_ON_STACK
    double *c = (double *)malloc(LG_MOTION_TAPE_C * sizeof(double));
    if (c == NULL)
        return 1;
#else
    double c[LG_MOTION_TAPE_C];
#endif
    double M[N * N], a[N + N_CONSTRAINTS];
    int failed = 0;
#if N_CONSTRAINTS
    double A[NC * N], W[N * NC], S[NC * NC];
    lg_motion_tape(t, y, y + N, lg_zeros, p, u, M, a, A, a + N, c);
    failed = lg_cholesky(M);
    if (!failed) {
        lg_cholesky_solve(M, a, 1);
        failed = lg_constrained_solve(M, a, a + N, A, W, S);
    }
#else
    double none[1];   /* A and γ: empty without constraints */
    lg_motion_tape(t, y, y + N, lg_zeros, p, u, M, a, none, none, c);
    failed = lg_cholesky(M);
    if (!failed)
        lg_cholesky_solve(M, a, 1);
#endif
    if (!failed) {
        memcpy(out, y + N, N * sizeof(double));
        memcpy(out + N, a, N * sizeof(double));
        /* LG_LANES directions at a time: their tangents in lanes (entry i of direction b at
         * [i·LG_LANES + b]), then one solve with the LG_LANES columns R (missing ones zero) */
        double D[2 * N * LG_LANES], P[N_PARAMS * LG_LANES + 1], R[N * LG_LANES],
            G[N_CONSTRAINTS * LG_LANES + 1];
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
            lg_motion_tangent(c, a, D, D + N * LG_LANES, P, R, G);
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
    }
#if LG_MOTION_TAPE_C > LG_TAPE_ON_STACK
    free(c);
#endif
    return failed;
#endif
