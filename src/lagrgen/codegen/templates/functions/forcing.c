    double M[N * N];
    lg_mf(t, y, y + N, lg_zeros, p, u, M, out);
    return 0;
