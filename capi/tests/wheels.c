/* The C API with reaction wheels, from C: the built-in arm with four wheels in a pyramid
 * (ofx_arm_with_wheels), wheel torque commands beyond the torque limit and one wheel pushed past
 * its speed limit, the wheel speeds and applied torques read back, save and restore, and the
 * calls refused with a status and a message. tests/python/test_capi.py builds it with the
 * system compiler and checks every number, printed as a hex float, against arm.simulate.
 *
 *   cc -std=c99 -Wall -Wextra -Werror -pedantic capi/tests/wheels.c -Iinclude \
 *      -Ltarget/release -lorbitflex_c -Wl,-rpath,$PWD/target/release -o wheels && ./wheels
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "orbitflex.h"

#define CHECK(call)                                                              \
    do {                                                                         \
        if ((call) != OFX_STATUS_OK) {                                           \
            fprintf(stderr, "%s failed: %s\n", #call, ofx_last_error());         \
            exit(1);                                                             \
        }                                                                        \
    } while (0)

/* A refused call: its status and message on stdout, for the test to read. */
static void refused(const char *what, OfxStatus status) {
    printf("refused %s %d %s\n", what, (int)status, ofx_last_error());
}

static void print_hex(const char *name, const double *v, size_t n) {
    printf("%s", name);
    for (size_t i = 0; i < n; i++) printf(" %a", v[i]);
    printf("\n");
}

enum { N = 7, W = 4, STEPS = 300 };

/* The commands of step `step`: up to +-70 N m (beyond the 60 N m limit), switching sign every
 * 25 steps; wheel 2 always pushed faster (70 N m). Exact arithmetic, as in the Python twin. */
static void commands(int step, double command[W]) {
    double sign = (step % 50 < 25) ? 1.0 : -1.0;
    for (int i = 0; i < W; i++) command[i] = sign * 70.0 * (i + 1) / 4.0;
    command[2] = 70.0;
}

int main(void) {
    /* the pyramid of examples/wheels.toml: axes (+-1, +-1, 1)/sqrt(3), centres 0.45 m out */
    const double a = 0.5773502691896258, p = 0.3181980515339464;
    const double sx[W] = {1, -1, -1, 1}, sy[W] = {1, 1, -1, -1};
    OfxWheel wheels[W];
    for (int i = 0; i < W; i++) {
        OfxWheel w = {{sx[i] * a, sy[i] * a, a}, {sx[i] * p, sy[i] * p, -0.45},
                      12.0, 0.25, 0.15, 60.0, 800.0, 0.0};
        wheels[i] = w;
    }
    OfxArm *bare, *arm;
    CHECK(ofx_arm_builtin("space_arm", &bare));
    CHECK(ofx_arm_with_wheels(bare, wheels, W, &arm));
    size_t k = 0, len = 0;
    CHECK(ofx_arm_wheel_count(arm, &k));
    CHECK(ofx_arm_state_len(arm, &len));
    printf("wheels %zu state %zu\n", k, len);

    double x0[13 + 4 * N + W];
    CHECK(ofx_arm_rest_state(arm, NULL, x0, len));
    x0[13 + 4 * N + 2] = 799.95; /* wheel 2 just under its 800 rad/s limit */
    OfxSimulator *sim;
    CHECK(ofx_simulator_new(arm, x0, len, 1e-3, &sim));

    double u[N] = {1.0, -0.5, 0.25, 2.0, 0.0, -1.0, 0.5};
    CHECK(ofx_simulator_set_motor_torque(sim, u, N));
    double command[W], speed[W], applied[W];
    unsigned char blob[4096];
    size_t written = 0;
    for (int step = 0; step < STEPS; step++) {
        commands(step, command);
        CHECK(ofx_simulator_set_wheel_torque(sim, command, W));
        CHECK(ofx_simulator_step(sim, 1));
        if (step == 199) CHECK(ofx_simulator_save(sim, blob, sizeof blob, &written));
    }
    size_t wlen = 0;
    CHECK(ofx_simulator_output_len(sim, OFX_OUTPUT_WHEEL_SPEED, &wlen));
    CHECK(ofx_simulator_output(sim, OFX_OUTPUT_WHEEL_SPEED, speed, W));
    CHECK(ofx_simulator_output(sim, OFX_OUTPUT_APPLIED_WHEEL_TORQUE, applied, W));
    double x[13 + 4 * N + W];
    CHECK(ofx_simulator_state(sim, x, len));
    printf("outputs %zu\n", wlen);
    print_hex("x", x, len);
    print_hex("wheel_speed", speed, W);
    print_hex("applied", applied, W);

    /* restore the state after step 200 and replay the last 100 steps: bit for bit */
    CHECK(ofx_simulator_restore(sim, blob, written));
    for (int step = 200; step < STEPS; step++) {
        commands(step, command);
        CHECK(ofx_simulator_set_wheel_torque(sim, command, W));
        CHECK(ofx_simulator_step(sim, 1));
    }
    double again[13 + 4 * N + W];
    CHECK(ofx_simulator_state(sim, again, len));
    printf("replay %s\n", memcmp(x, again, sizeof x) == 0 ? "bit-exact" : "DIFFERS");

    /* refused: a wrong count, NaN, no wheels, a bad wheel, a state of another wheel count */
    refused("count", ofx_simulator_set_wheel_torque(sim, command, 3));
    double nan_command[W] = {0.0, NAN, 0.0, 0.0};
    refused("nan", ofx_simulator_set_wheel_torque(sim, nan_command, W));
    OfxSimulator *plain;
    double xb[13 + 4 * N];
    CHECK(ofx_arm_rest_state(bare, NULL, xb, 13 + 4 * N));
    CHECK(ofx_simulator_new(bare, xb, 13 + 4 * N, 1e-3, &plain));
    refused("no_wheels", ofx_simulator_set_wheel_torque(plain, command, W));
    refused("restore", ofx_simulator_restore(plain, blob, written));
    CHECK(ofx_simulator_output_len(plain, OFX_OUTPUT_WHEEL_SPEED, &wlen));
    printf("plain outputs %zu\n", wlen);
    OfxWheel bad[2] = {wheels[0], wheels[1]};
    bad[1].spin_inertia = -0.25;
    OfxArm *out = NULL;
    refused("bad_wheel", ofx_arm_with_wheels(bare, bad, 2, &out));
    refused("none", ofx_arm_with_wheels(bare, wheels, 0, &out));
    refused("null", ofx_arm_with_wheels(bare, NULL, 2, &out));

    ofx_simulator_free(plain);
    ofx_simulator_free(sim);
    ofx_arm_free(arm);
    ofx_arm_free(bare);
    return 0;
}
