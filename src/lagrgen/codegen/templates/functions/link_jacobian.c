    /* y = [q, point (3), the link's index]: out = J (6×N) with [ẋ; ω] = J·q̇ at the point
     * x = p + R·point: for each node i carrying the link or above it, its twist [ω_i; v_i] (per
     * unit rate, Plücker coordinates at the fixed origin) adds [v_i + ω_i × x; ω_i] to the column
     * of its coordinate; by the link's own function (lg_link_jacobians: its chain only), or by
     * walking the twists of all nodes (lg_link_frames). 1 for an index out of range. */
#if N_LINKS
    const double *point = y + N;
    const int k = lg_link_argument(y);
    if (k < 0)
        return 1;
#if LG_LINK_CHAINS
#define LG_LINK_JACOBIAN_WORK 0
    (void)t, (void)u, (void)work;
    return lg_link_jacobians[k](y, p, point, out);
#else
#define LG_LINK_JACOBIAN_WORK (12 * N_LINKS + 6 * N_LINK_NODES)
    const double *twists = work + 12 * N_LINKS;
    LG_TRY(lg_link_frames(t, y, lg_zeros, lg_zeros, p, u, work, work + 12 * N_LINKS));
    const double *R = work + 12 * k, *o = R + 9;
    double x[3];
    lg_link_point(R, o, point, x);
    memset(out, 0, 6 * N * sizeof(double));
    for (int i = lg_link_node[k]; i >= 0; i = lg_link_parent[i]) {
        const double *w = twists + 6 * i, *v = w + 3;
        const int c = lg_link_coordinate[i];
        out[c] += v[0] + w[1] * x[2] - w[2] * x[1];
        out[N + c] += v[1] + w[2] * x[0] - w[0] * x[2];
        out[2 * N + c] += v[2] + w[0] * x[1] - w[1] * x[0];
        out[3 * N + c] += w[0];
        out[4 * N + c] += w[1];
        out[5 * N + c] += w[2];
    }
    return 0;
#endif
#else
#define LG_LINK_JACOBIAN_WORK 0
    (void)t, (void)y, (void)p, (void)u, (void)out, (void)work;
    return 1;
#endif
