/* The C example's loop (examples/c/slew.c without the printing), timed: per RK4 step, read
 * theta and theta_dot, compute a motor PD, set the torques, step once. Prints seconds per step
 * (median of ROUNDS runs of STEPS steps; wall time, or the process's CPU time with "cpu").
 * Usage: cosim_loop [STEPS [ROUNDS [wall|cpu]]]. Built and run by benches/cosim.py. */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "orbitflex.h"

#define N 7

static clockid_t which_clock = CLOCK_MONOTONIC;

static double now(void) {
    struct timespec ts;
    clock_gettime(which_clock, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv) {
    int steps = argc > 1 ? atoi(argv[1]) : 10000, rounds = argc > 2 ? atoi(argv[2]) : 5;
    if (argc > 3 && strcmp(argv[3], "cpu") == 0) which_clock = CLOCK_PROCESS_CPUTIME_ID;
    const double kp[N] = {300.0, 1250.0, 1250.0, 650.0, 85.0, 42.0, 16.0};
    const double kd[N] = {100.0, 670.0, 670.0, 300.0, 27.0, 13.0, 4.2};
    OfxArm *arm;
    OfxSimulator *sim;
    double x[41], theta[N], theta_dot[N], u[N], times[64];
    if (ofx_arm_builtin("space_arm", &arm) || ofx_arm_rest_state(arm, NULL, x, 41) ||
        ofx_simulator_new(arm, x, 41, 1e-3, &sim)) {
        fprintf(stderr, "%s\n", ofx_last_error());
        return 1;
    }
    if (rounds > 64) rounds = 64;
    for (int r = 0; r < rounds; r++) {
        ofx_simulator_reset(sim, x, 41);
        double start = now();
        for (int k = 0; k < steps; k++) {
            ofx_simulator_output(sim, OFX_OUTPUT_THETA, theta, N);
            ofx_simulator_output(sim, OFX_OUTPUT_THETA_DOT, theta_dot, N);
            for (int i = 0; i < N; i++) u[i] = kp[i] * (0.2 - theta[i]) - kd[i] * theta_dot[i];
            ofx_simulator_set_motor_torque(sim, u, N);
            if (ofx_simulator_step(sim, 1)) {
                fprintf(stderr, "%s\n", ofx_last_error());
                return 1;
            }
        }
        times[r] = (now() - start) / steps;
    }
    qsort(times, (size_t)rounds, sizeof times[0], cmp);
    printf("%.6e\n", times[rounds / 2]);
    ofx_simulator_free(sim);
    ofx_arm_free(arm);
    return 0;
}
