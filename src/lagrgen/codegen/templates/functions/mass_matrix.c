    double F[N];
    (void)u;
    lg_mf(t, y, lg_zeros, lg_zeros, p, lg_zeros, out, F);
    return 0;
