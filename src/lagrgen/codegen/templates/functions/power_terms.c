#define LG_POWER_TERMS_WORK (N_OUTPUTS + 1)
    return lg_outputs(t, y, y + N, lg_zeros, p, u, work, out);
