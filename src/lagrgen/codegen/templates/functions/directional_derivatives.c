    /* out = [ẏ; then per direction s: J·dy_s + ∂ẏ/∂p·dp_s]. M, F (and A, γ) are evaluated once,
     * with the tape c of their forward-mode coefficients (kernel motion_tape); each direction then
     * runs the tangent program (motion_tangent: δR = δF − δM·q̈ + δAᵀ·λ, δG = δγ − δA·q̈) and
     * solves M·δq̈ = δR with the rhs's factor of M (or the saddle point [M −Aᵀ; A 0]). */
#if LG_MOTION_TAPE_C > LG_TAPE_ON_STACK
    double *c = (double *)malloc(LG_MOTION_TAPE_C * sizeof(double));
    if (c == NULL)
        return 1;
#else
    double c[LG_MOTION_TAPE_C];
#endif
    double M[N * N], a[N + N_CONSTRAINTS], dG[N_CONSTRAINTS + 1];
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
    lg_motion_tape(t, y, y + N, lg_zeros, p, u, M, a, dG, dG, c);
    failed = lg_cholesky(M);
    if (!failed)
        lg_cholesky_solve(M, a, 1);
#endif
    if (!failed) {
        memcpy(out, y + N, N * sizeof(double));
        memcpy(out + N, a, N * sizeof(double));
        for (int s = 0; s < k; ++s) {
            const double *ds = dy + (size_t)2 * N * s;
            double *o = out + (size_t)2 * N * (s + 1);
            memcpy(o, ds + N, N * sizeof(double));
            lg_motion_tangent(c, a, ds, ds + N, dp + (size_t)N_PARAMS * s, o + N, dG);
#if N_CONSTRAINTS
            lg_saddle_columns(M, A, W, S, o + N, dG, 1);
#else
            lg_cholesky_solve(M, o + N, 1);
#endif
        }
    }
#if LG_MOTION_TAPE_C > LG_TAPE_ON_STACK
    free(c);
#endif
    return failed;
