#define LG_MASS_MATRIX_WORK N
    (void)u;
    return lg_mf(t, y, lg_zeros, lg_zeros, p, lg_zeros, out, work);
