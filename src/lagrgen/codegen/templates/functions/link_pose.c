    /* y = [q, point (3), the link's index]: out = [x (3), R (3×3, row-major)] with
     * x = p + R·point, from the link's own function (lg_link_poses: its chain only) or from the
     * frames of all links (lg_link_frames). 1 for an index out of range. */
#if N_LINKS
    const double *point = y + N;
    const int k = lg_link_argument(y);
    if (k < 0)
        return 1;
#if LG_LINK_CHAINS
#define LG_LINK_POSE_WORK 0
    (void)t, (void)u, (void)work;
    return lg_link_poses[k](y, p, point, out);
#else
#define LG_LINK_POSE_WORK (12 * N_LINKS + 6 * N_LINK_NODES)
    LG_TRY(lg_link_frames(t, y, lg_zeros, lg_zeros, p, u, work, work + 12 * N_LINKS));
    const double *R = work + 12 * k, *o = R + 9;
    lg_link_point(R, o, point, out);
    memcpy(out + 3, R, 9 * sizeof(double));
    return 0;
#endif
#else
#define LG_LINK_POSE_WORK 0
    (void)t, (void)y, (void)p, (void)u, (void)out, (void)work;
    return 1;
#endif
