    /* y = [q, q̇, q̈, λ]; out = ∂r/∂p (NI×N_PARAMS) of r = [M·q̈ − F − Aᵀλ; A·q̈ − γ]:
     * −(∂F/∂p − ∂(M·q̈)/∂p) − ∂(Aᵀλ)/∂p, then the constraint rows −(∂γ/∂p − ∂(A·q̈)/∂p). */
#define LG_RESIDUAL_PARAMETER_JACOBIAN_WORK (N_CONSTRAINTS ? (N + N_CONSTRAINTS) * N_PARAMS : 0)
#if N_PARAMS
    const double *q = y, *qd = y + N, *a = y + 2 * N;
    LG_TRY(lg_parameter_b(t, q, qd, a, p, u, out));
    for (int i = 0; i < N * N_PARAMS; ++i)
        out[i] = -out[i];
#if N_CONSTRAINTS
    double *Hp = work, *Gp = Hp + N * N_PARAMS;
    LG_TRY(lg_constraint_parameter_jacobian(t, q, qd, a, p, u, Hp, Gp));
    for (int i = 0; i < N * N_PARAMS; ++i)
        out[i] -= Hp[i];
    for (int i = 0; i < NC * N_PARAMS; ++i)
        out[N * N_PARAMS + i] = -Gp[i];
#endif
#else
    (void)t, (void)y, (void)p, (void)u, (void)out;
#endif
    return 0;
