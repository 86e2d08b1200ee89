    /* y = [q, point (3), the link's index]: out = [x (3), R (3×3, row-major)] with
     * x = p + R·point, from the link frames (lg_link_frames). 1 for an index out of range. */
#if N_LINKS
#define LG_LINK_POSE_WORK (12 * N_LINKS + 6 * N_LINK_NODES)
    const double *point = y + N;
    const int k = (int)y[N + 3];
    if (!(y[N + 3] >= 0.0 && k < N_LINKS))
        return 1;
    LG_TRY(lg_link_frames(t, y, lg_zeros, lg_zeros, p, u, work, work + 12 * N_LINKS));
    const double *R = work + 12 * k, *o = R + 9;
    for (int r = 0; r < 3; ++r)
        out[r] = o[r] + R[3 * r] * point[0] + R[3 * r + 1] * point[1] + R[3 * r + 2] * point[2];
    memcpy(out + 3, R, 9 * sizeof(double));
    return 0;
#else
#define LG_LINK_POSE_WORK 0
    (void)t, (void)y, (void)p, (void)u, (void)out, (void)work;
    return 1;
#endif
