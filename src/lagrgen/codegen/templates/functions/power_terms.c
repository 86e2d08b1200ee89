    double outputs[N_OUTPUTS + 1];
    lg_outputs(t, y, y + N, lg_zeros, p, u, outputs, out);
    return 0;
