#if LG_RECURSIVE
    (void)u;
    lg_tree_mass_matrix(t, y, p, out);
#else
    double F[N];
    (void)u;
    lg_mf(t, y, lg_zeros, lg_zeros, p, lg_zeros, out, F);
#endif
    return 0;
