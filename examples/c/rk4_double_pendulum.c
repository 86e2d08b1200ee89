/* The double pendulum of examples/double_pendulum.py, exported as plain C by lagrgen and integrated
 * here with the classic fixed-step fourth-order Runge-Kutta method. No Python is involved.
 *
 *   python -m lagrgen export-c examples/double_pendulum.py --out build_c
 *   cc -O2 -I build_c examples/c/rk4_double_pendulum.c build_c/double_pendulum_model.c -lm -o rk4
 *   ./rk4 T_END STEPS THETA1 THETA2 F      (defaults: 10 10000 0.5 0 0)
 *
 * Prints the final state y = [theta1, theta2, theta1_dot, theta2_dot], one number per line.
 */
#include <stdio.h>
#include <stdlib.h>

#include "double_pendulum_model.h"

#define NS double_pendulum_N_STATES

/* ydot = f(t, y); exits with a message if the mass matrix is not positive definite. */
static void derivative(double t, const double *y, const double *u, double *ydot)
{
    if (double_pendulum_rhs(t, y, double_pendulum_defaults, u, ydot)) {
        fprintf(stderr, "mass matrix not positive definite at t = %g\n", t);
        exit(1);
    }
}

/* One RK4 step of size h from (t, y), in place. */
static void rk4_step(double t, double h, double *y, const double *u)
{
    double k1[NS], k2[NS], k3[NS], k4[NS], tmp[NS];
    derivative(t, y, u, k1);
    for (int i = 0; i < NS; ++i) tmp[i] = y[i] + 0.5 * h * k1[i];
    derivative(t + 0.5 * h, tmp, u, k2);
    for (int i = 0; i < NS; ++i) tmp[i] = y[i] + 0.5 * h * k2[i];
    derivative(t + 0.5 * h, tmp, u, k3);
    for (int i = 0; i < NS; ++i) tmp[i] = y[i] + h * k3[i];
    derivative(t + h, tmp, u, k4);
    for (int i = 0; i < NS; ++i)
        y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
}

int main(int argc, char **argv)
{
    const double t_end = argc > 1 ? atof(argv[1]) : 10.0;
    const long steps = argc > 2 ? atol(argv[2]) : 10000;
    double y[NS] = {argc > 3 ? atof(argv[3]) : 0.5, argc > 4 ? atof(argv[4]) : 0.0, 0.0, 0.0};
    const double u[double_pendulum_N_INPUTS] = {argc > 5 ? atof(argv[5]) : 0.0};
    const double h = t_end / (double)steps;
    for (long k = 0; k < steps; ++k)
        rk4_step(k * h, h, y, u);
    for (int i = 0; i < NS; ++i)
        printf("%.17g\n", y[i]);
    return 0;
}
