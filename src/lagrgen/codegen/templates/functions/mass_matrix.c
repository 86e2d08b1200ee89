#if LG_RECURSIVE
#define LG_MASS_MATRIX_WORK 0
    (void)u, (void)work;
    return lg_tree_mass_matrix(t, y, p, out);
#else
#define LG_MASS_MATRIX_WORK N
    (void)u;
    return lg_mf(t, y, lg_zeros, lg_zeros, p, lg_zeros, out, work);
#endif
