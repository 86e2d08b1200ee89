    double power[2];
    lg_outputs(t, y, y + N, lg_zeros, p, u, out, power);
    return 0;
