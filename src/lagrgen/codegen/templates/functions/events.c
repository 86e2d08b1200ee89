#if N_EVENTS
    return lg_events(t, y, y + N, lg_zeros, p, u, out);
#else
    (void)t, (void)y, (void)p, (void)u, (void)out;
    return 0;
#endif
