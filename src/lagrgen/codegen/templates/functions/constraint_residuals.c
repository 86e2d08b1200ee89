#if N_CONSTRAINTS
    return lg_constraint_residuals(t, y, y + N, lg_zeros, p, u, out);
#else
    (void)t, (void)y, (void)p, (void)u, (void)out;
    return 0;
#endif
