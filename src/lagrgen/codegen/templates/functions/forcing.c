#define LG_FORCING_WORK (N * N)
    return lg_mf(t, y, y + N, lg_zeros, p, u, work, out);
