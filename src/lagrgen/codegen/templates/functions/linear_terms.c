    double F[N], B[N * 2 * N];
    double *dF_dq = out + N * N, *dF_dqd = out + 2 * N * N, *dF_du = out + 3 * N * N;
    lg_mf(t, y, y + N, lg_zeros, p, u, out, F);
    lg_jacobian_b(t, y, y + N, lg_zeros, p, u, B);
    for (int i = 0; i < N; ++i) {
        memcpy(dF_dq + i * N, B + i * 2 * N, N * sizeof(double));
        memcpy(dF_dqd + i * N, B + i * 2 * N + N, N * sizeof(double));
    }
    lg_dF_du(t, y, y + N, lg_zeros, p, u, dF_du);
    return 0;
