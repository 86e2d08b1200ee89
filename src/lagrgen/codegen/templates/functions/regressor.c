    /* out = Y (N × N_INERTIAL) = ∂(M·q̈ − F)/∂π at q̈ = a (y = [q, q̇, a]): for a spatial tree
     * directly from each body's regressor (lg_tree_regressor); otherwise minus the columns of
     * P = ∂F/∂p − ∂(M·a)/∂p of the inertial parameters (M·q̈ − F is linear in π). */
#if N_INERTIAL && LG_TREE_POSES
#define LG_REGRESSOR_WORK 0
    (void)work;
    return lg_tree_regressor(t, y, y + N, y + 2 * N, p, u, out);
#elif N_INERTIAL
#define LG_REGRESSOR_WORK (N * N_PARAMS)
    LG_TRY(lg_parameter_b(t, y, y + N, y + 2 * N, p, u, work));
    for (int i = 0; i < N; ++i)
        for (int k = 0; k < N_INERTIAL; ++k)
            out[i * N_INERTIAL + k] = -work[i * N_PARAMS + lg_inertial_index[k]];
    return 0;
#else
#define LG_REGRESSOR_WORK 0
    (void)t, (void)y, (void)p, (void)u, (void)out, (void)work;
    return 0;
#endif
