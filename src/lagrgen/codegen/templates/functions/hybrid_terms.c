    LG_TRY(lg_mf(t, y, y + N, lg_zeros, p, u, out, out + N * N));
#if N_CONSTRAINTS
    LG_TRY(lg_constraints(t, y, y + N, lg_zeros, p, u, out + N * N + N,
                          out + N * N + N + N_CONSTRAINTS * N));
#endif
#if N_HYBRID
    LG_TRY(lg_nonsmooth(t, y, y + N, lg_zeros, p, u,
                        out + N * N + N + N_CONSTRAINTS * N + N_CONSTRAINTS));
#endif
    return 0;
