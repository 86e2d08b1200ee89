    /* y = [q, q̇, q̈, λ]; out = [r (NI), ∂r/∂[q, q̇] (NI×2N), ∂r/∂[q̈, λ] (NI×NI), ∂r/∂u (NI×N_INPUTS)]
     * for r = [M·q̈ − F − Aᵀλ; A·q̈ − γ], NI = N + N_CONSTRAINTS rows. ∂r/∂[q, q̇] = −B − [H | 0]
     * with B = [∂F/∂q − ∂(M·q̈)/∂q | ∂F/∂q̇] and H = ∂(Aᵀλ)/∂q; the constraint rows are −G. */
#define LG_RESIDUAL_TERMS_WORK \
    (3 * N * N + N_CONSTRAINTS * (3 * N + 1) + (N_CONSTRAINTS ? N * N : 0))
    enum { NI = N + N_CONSTRAINTS };
    const double *q = y, *qd = y + N, *a = y + 2 * N;
    double *r = out, *dr_dy = r + NI, *dr_da = dr_dy + NI * 2 * N, *dr_du = dr_da + NI * NI;
    double *M = work, *B = M + N * N;
    LG_TRY(lg_mf(t, q, qd, a, p, u, M, r));
    for (int i = 0; i < N; ++i) {
        double s = -r[i];
        for (int j = 0; j < N; ++j)
            s += M[i * N + j] * a[j];
        r[i] = s;
    }
    LG_TRY(lg_jacobian_b(t, q, qd, a, p, u, B));
    for (int i = 0; i < N; ++i)
        for (int j = 0; j < 2 * N; ++j)
            dr_dy[i * 2 * N + j] = -B[i * 2 * N + j];
    memset(dr_da, 0, (size_t)NI * NI * sizeof(double));
    for (int i = 0; i < N; ++i)
        memcpy(dr_da + i * NI, M + i * N, N * sizeof(double));
#if N_INPUTS
    LG_TRY(lg_dF_du(t, q, qd, a, p, u, dr_du));
    for (int i = 0; i < N * N_INPUTS; ++i)
        dr_du[i] = -dr_du[i];
    memset(dr_du + N * N_INPUTS, 0, (size_t)N_CONSTRAINTS * N_INPUTS * sizeof(double));
#else
    (void)dr_du;
#endif
#if N_CONSTRAINTS
    double *A = B + 2 * N * N, *gamma = A + NC * N, *H = gamma + NC, *G = H + N * N;
    LG_TRY(lg_constraints(t, q, qd, a, p, u, A, gamma));
    LG_TRY(lg_constraint_jacobian(t, q, qd, a, p, u, H, G));
    for (int k = 0; k < NC; ++k) {
        double s = -gamma[k];
        for (int j = 0; j < N; ++j) {
            r[j] -= A[k * N + j] * a[N + k];
            s += A[k * N + j] * a[j];
            dr_da[j * NI + N + k] = -A[k * N + j];
            dr_da[(N + k) * NI + j] = A[k * N + j];
        }
        r[N + k] = s;
        for (int j = 0; j < 2 * N; ++j)
            dr_dy[(N + k) * 2 * N + j] = -G[k * 2 * N + j];
    }
    for (int i = 0; i < N; ++i)
        for (int j = 0; j < N; ++j)
            dr_dy[i * 2 * N + j] -= H[i * N + j];
#endif
    return 0;
