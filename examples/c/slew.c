/*
 * A slew of the built-in space arm, stepped from C through orbitflex's C API: a motor PD
 * written here tracks a quintic slew of every joint by 0.3 rad in 2 s, one RK4 step of 1 ms at
 * a time, free floating. Prints the link angles every 0.5 s and the final base attitude and
 * momentum; examples/c/slew.py does the same run in Python and prints the same digits.
 *
 * Build and run (from the repository root, after `cargo build --release -p orbitflex-capi`):
 *   cc -std=c99 -O2 -Wall -Wextra -pedantic -ffp-contract=off examples/c/slew.c -Iinclude \
 *      -Ltarget/release -lorbitflex_c -Wl,-rpath,"$PWD/target/release" -o slew && ./slew
 * (-ffp-contract=off: no fused multiply-adds, so that the PD's arithmetic is Python's.)
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "orbitflex.h"

#define N 7

/* Stop with the library's message if a call fails. */
static void check(OfxStatus status, const char *what) {
    if (status != OFX_STATUS_OK) {
        fprintf(stderr, "%s failed (status %d): %s\n", what, (int)status, ofx_last_error());
        exit(1);
    }
}

/* The quintic rest-to-rest profile from 0 to 1 over T seconds. */
static double quintic(double t, double T) {
    double s = t / T;
    if (s < 0.0) s = 0.0;
    if (s > 1.0) s = 1.0;
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s);
}

int main(void) {
    /* motor PD gains per joint (N m/rad, N m s/rad), about a 1 Hz bandwidth on this arm */
    const double kp[N] = {300.0, 1250.0, 1250.0, 650.0, 85.0, 42.0, 16.0};
    const double kd[N] = {100.0, 670.0, 670.0, 300.0, 27.0, 13.0, 4.2};
    const double dt = 1e-3, T = 2.0, target = 0.3;
    const int steps = 3000;

    OfxArm *arm = NULL;
    check(ofx_arm_builtin("space_arm", &arm), "ofx_arm_builtin");
    size_t n = 0, len = 0;
    check(ofx_arm_dof(arm, &n), "ofx_arm_dof");
    check(ofx_arm_state_len(arm, &len), "ofx_arm_state_len");
    if (n != N) {
        fprintf(stderr, "expected %d joints, the arm has %zu\n", N, n);
        return 1;
    }
    double *x = malloc(len * sizeof *x);
    check(ofx_arm_rest_state(arm, NULL, x, len), "ofx_arm_rest_state");

    OfxSimulator *sim = NULL;
    check(ofx_simulator_new(arm, x, len, dt, &sim), "ofx_simulator_new");
    ofx_arm_free(arm); /* the simulator holds its own copy */

    /* a refused call: a status and a message, nothing changed */
    double wrong[3] = {0.0, 0.0, 0.0};
    OfxStatus status = ofx_simulator_set_motor_torque(sim, wrong, 3);
    fprintf(stderr, "expected refusal (status %d): %s\n", (int)status, ofx_last_error());

    double q[N], theta[N], theta_dot[N], u[N];
    unsigned char *saved = NULL;
    size_t saved_len = 0;
    for (int k = 0; k < steps; k++) {
        double t = (double)k * dt;
        double ref = target * quintic(t, T);
        check(ofx_simulator_output(sim, OFX_OUTPUT_THETA, theta, N), "theta");
        check(ofx_simulator_output(sim, OFX_OUTPUT_THETA_DOT, theta_dot, N), "theta_dot");
        for (int i = 0; i < N; i++) u[i] = kp[i] * (ref - theta[i]) - kd[i] * theta_dot[i];
        check(ofx_simulator_set_motor_torque(sim, u, N), "set_motor_torque");
        check(ofx_simulator_step(sim, 1), "step");
        if ((k + 1) % 500 == 0) {
            double now;
            check(ofx_simulator_time(sim, &now), "time");
            check(ofx_simulator_output(sim, OFX_OUTPUT_Q, q, N), "q");
            printf("t = %.3f s  q =", now);
            for (int i = 0; i < N; i++) printf(" %.12e", q[i]);
            printf("\n");
        }
        if (k + 1 == 2500) { /* save at 2.5 s, to replay the last 0.5 s below */
            check(ofx_simulator_saved_len(sim, &saved_len), "saved_len");
            saved = malloc(saved_len);
            check(ofx_simulator_save(sim, saved, saved_len, &saved_len), "save");
        }
    }
    double pose[7], momentum[6], energy;
    check(ofx_simulator_output(sim, OFX_OUTPUT_BASE_POSE, pose, 7), "base_pose");
    check(ofx_simulator_output(sim, OFX_OUTPUT_MOMENTUM, momentum, 6), "momentum");
    check(ofx_simulator_output(sim, OFX_OUTPUT_ENERGY, &energy, 1), "energy");
    printf("base quaternion (x, y, z, w) = %.12e %.12e %.12e %.12e\n", pose[3], pose[4], pose[5], pose[6]);
    printf("momentum (angular; linear) =");
    for (int i = 0; i < 6; i++) printf(" %.12e", momentum[i]);
    printf("\nenergy = %.12e J\n", energy);

    /* replay the last 0.5 s from the saved state, with the last torque held: deterministic */
    double *end = malloc(len * sizeof *end);
    check(ofx_simulator_restore(sim, saved, saved_len), "restore");
    check(ofx_simulator_step(sim, 500), "replay");
    check(ofx_simulator_state(sim, end, len), "state");
    check(ofx_simulator_restore(sim, saved, saved_len), "restore");
    check(ofx_simulator_step(sim, 500), "replay");
    check(ofx_simulator_state(sim, x, len), "state");
    printf("replay from the saved state: %s\n", memcmp(x, end, len * sizeof *x) == 0 ? "bit-exact" : "DIFFERENT");

    ofx_simulator_free(sim);
    free(saved);
    free(end);
    free(x);
    return 0;
}
