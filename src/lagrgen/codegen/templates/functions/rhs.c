    double M[N * N];
    lg_mf(t, y, y + N, lg_zeros, p, u, M, out + N);
    if (lg_cholesky(M))
        return 1;
    lg_cholesky_solve(M, out + N, 1);
    memcpy(out, y + N, N * sizeof(double));
    return 0;
