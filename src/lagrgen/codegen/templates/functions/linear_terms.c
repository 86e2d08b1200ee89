#define LG_LINEAR_TERMS_WORK (N + 2 * N * N)
    double *F = work, *B = F + N;
    double *dF_dq = out + N * N, *dF_dqd = out + 2 * N * N, *dF_du = out + 3 * N * N;
    LG_TRY(lg_mf(t, y, y + N, lg_zeros, p, u, out, F));
    LG_TRY(lg_jacobian_b(t, y, y + N, lg_zeros, p, u, B));
    for (int i = 0; i < N; ++i) {
        memcpy(dF_dq + i * N, B + i * 2 * N, N * sizeof(double));
        memcpy(dF_dqd + i * N, B + i * 2 * N + N, N * sizeof(double));
    }
    return lg_dF_du(t, y, y + N, lg_zeros, p, u, dF_du);
