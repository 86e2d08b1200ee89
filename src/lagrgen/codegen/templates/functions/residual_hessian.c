    /* out = H = ∇²_z(Σ mu_i·r_i) (symmetric, N_POINT × N_POINT) for z = [q, q̇, q̈, λ, u] and
     * y = [q, q̇, a, mu], a = [q̈, λ]. A spatial tree: the second-order derivatives of its inverse
     * dynamics τ contracted with mu (lg_tree_hessian: the blocks qq, q̇q̇, q q̇ and q̈ q, mirrored
     * here), minus ∇²(Σ mu_i·Q_i) of its other forces (tree_q_hessian); otherwise the symbolic
     * second derivatives (residual_hessian, or tree_residual_hessian of a planar tree or a free
     * base). */
    enum { NP = 3 * N + N_CONSTRAINTS + N_INPUTS };
    const double *q = y, *qd = y + N, *a = y + 2 * N, *mu = a + N + N_CONSTRAINTS;
#if LG_RECURSIVE && LG_TREE_HESSIAN
#define LG_RESIDUAL_HESSIAN_WORK (TREE_NN * TREE_NODE_W + LG_TREE_HESSIAN_WORK + TREE_NNZ_QH + 1)
    double *node = work, *scratch = node + TREE_NN * TREE_NODE_W;
    double *HQ = scratch + LG_TREE_HESSIAN_WORK;
    memset(out, 0, (size_t)NP * NP * sizeof(double));
    LG_TRY(lg_tree_nodes(t, q, qd, lg_zeros, p, u, node));
    lg_tree_hessian(node, qd, a, mu, out, NP, scratch);
    for (int r = 0; r < N; ++r)
        for (int c = 0; c < N; ++c) {
            out[(N + c) * NP + r] = out[r * NP + N + c];
            out[r * NP + 2 * N + c] = out[(2 * N + c) * NP + r];
        }
    LG_TRY(lg_tree_q_hessian(t, q, qd, a, p, u, mu, HQ));
    for (int e = 0; e < TREE_NNZ_QH; ++e) {
        const int r = lg_tree_qh[2 * e], c = lg_tree_qh[2 * e + 1];
        out[r * NP + c] -= HQ[e];
        if (r != c)
            out[c * NP + r] -= HQ[e];
    }
    return 0;
#elif LG_RECURSIVE
#define LG_RESIDUAL_HESSIAN_WORK 0
    (void)work;
    return lg_tree_residual_hessian(t, q, qd, a, p, u, mu, out);
#else
#define LG_RESIDUAL_HESSIAN_WORK 0
    (void)work;
    return lg_residual_hessian(t, q, qd, a, p, u, mu, out);
#endif
