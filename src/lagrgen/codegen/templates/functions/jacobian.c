    double M[N * N], a[N], B[N * 2 * N];
    lg_mf(t, y, y + N, lg_zeros, p, u, M, a);
    if (lg_cholesky(M))
        return 1;
    lg_cholesky_solve(M, a, 1);
    lg_jacobian_b(t, y, y + N, a, p, u, B);
    lg_cholesky_solve(M, B, 2 * N);
    memset(out, 0, (size_t)2 * N * N * sizeof(double));
    for (int i = 0; i < N; ++i)
        out[i * 2 * N + N + i] = 1.0;
    memcpy(out + 2 * N * N, B, (size_t)2 * N * N * sizeof(double));
    return 0;
