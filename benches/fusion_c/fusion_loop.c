/*
 * fusion_loop.c - cost per update of x-io's Fusion AHRS C library, plain C loop.
 *
 * Measures FusionAhrsUpdate (9d: gyro+acc+mag) or FusionAhrsUpdateNoMagnetometer
 * (6d) with Fusion's default settings, as the `imufusion` Python package uses
 * them (FusionAhrsInitialise = fusionAhrsDefaultSettings: NWU, gain 0.5, no
 * gyro-overrange check, acceleration/magnetic rejection off; then
 * FusionAhrsSetSamplePeriod(1/286) like benches/python/bench_peers.py), built
 * with FUSION_USE_NORMAL_SQRT as imufusion's setup.py does.
 * Fusion's sources are NOT in this repo: build with benches/fusion_c/build.sh.
 *
 *   target/fusion_c/fusion_loop MODE [SAMPLES=20000] [PASSES=3]
 *     MODE = 9d | 6d | none   (none: only builds the input, for callgrind baselines)
 *
 * The synthetic input (N samples at 286 Hz) is built before timing: 4 s rest,
 * then 10 s rotation about a wandering axis w = 1.5*(sin .7t, cos .5t, .6 sin .3t)
 * rad/s (moving while fmod(t,14) >= 4), orientation integrated exactly per step;
 * acc = q^-1 (0,0,9.81) in g, mag = q^-1 (0,20,-40) uT, gyro in deg/s, small
 * deterministic noise. Each pass re-initialises the filter and runs all N
 * updates; the time is CLOCK_PROCESS_CPUTIME_ID, best of PASSES. Prints one line
 *   {"mode": "9d", "samples": N, "ns_per_update": ..., "checksum": ...}
 * checksum = sum of the final quaternion's components weighted 1..4 (6d/9d) or
 * of the input (none). Set FUSION_LOOP_VERBOSE=1 for the final tilt error on stderr.
 *
 * Instructions per update: valgrind --tool=callgrind --callgrind-out-file=/dev/null
 * for PASSES=1 and 2; (Ir(2) - Ir(1)) / SAMPLES.
 */
#define _DEFAULT_SOURCE /* clock_gettime, M_PI */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "Fusion.h"

#define RATE_HZ 286.0

typedef struct { double w, x, y, z; } quat;

static quat qmul(quat a, quat b) {
    quat r = {
        a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z,
        a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
        a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
        a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w,
    };
    return r;
}

/* v_body = q^-1 * v_world * q  (q maps body to world) */
static void rotate_inv(quat q, const double v[3], double out[3]) {
    quat p = {0.0, v[0], v[1], v[2]};
    quat qc = {q.w, -q.x, -q.y, -q.z};
    quat r = qmul(qmul(qc, p), q);
    out[0] = r.x; out[1] = r.y; out[2] = r.z;
}

static void body_rate(double t, double w[3]) {
    if (fmod(t, 14.0) >= 4.0) {
        w[0] = 1.5 * sin(0.7 * t);
        w[1] = 1.5 * cos(0.5 * t);
        w[2] = 1.5 * 0.6 * sin(0.3 * t);
    } else {
        w[0] = w[1] = w[2] = 0.0;
    }
}

static uint64_t rng_state = 0x9E3779B97F4A7C15ull;
static double noise(void) { /* deterministic, roughly N(0,1): sum of 4 uniforms */
    double s = 0.0;
    for (int i = 0; i < 4; i++) {
        rng_state ^= rng_state << 13; rng_state ^= rng_state >> 7; rng_state ^= rng_state << 17;
        s += (double) (rng_state >> 11) * (1.0 / 9007199254740992.0) - 0.5;
    }
    return s * 1.7320508075688772; /* var(sum of 4 U(-.5,.5)) = 1/3 */
}

static double now_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double) ts.tv_sec * 1e9 + (double) ts.tv_nsec;
}

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: %s 9d|6d|none [SAMPLES=20000] [PASSES=3]\n", argv[0]);
        return 2;
    }
    const char *mode = argv[1];
    const int m9 = strcmp(mode, "9d") == 0, m6 = strcmp(mode, "6d") == 0;
    if (!m9 && !m6 && strcmp(mode, "none") != 0) {
        fprintf(stderr, "MODE must be 9d, 6d or none\n");
        return 2;
    }
    const long n = argc > 2 ? atol(argv[2]) : 20000;
    const int passes = argc > 3 ? atoi(argv[3]) : 3;
    if (n <= 0 || passes <= 0) {
        fprintf(stderr, "SAMPLES and PASSES must be > 0\n");
        return 2;
    }

    /* ---- input, built before timing ---- */
    FusionVector *gyr = malloc(sizeof *gyr * (size_t) n);
    FusionVector *acc = malloc(sizeof *acc * (size_t) n);
    FusionVector *mag = malloc(sizeof *mag * (size_t) n);
    if (!gyr || !acc || !mag) return 1;
    const double dt = 1.0 / RATE_HZ, rad2deg = 180.0 / M_PI;
    const double g_world[3] = {0.0, 0.0, 9.81}, m_world[3] = {0.0, 20.0, -40.0};
    quat q = {1.0, 0.0, 0.0, 0.0};
    double input_sum = 0.0;
    for (long k = 0; k < n; k++) {
        const double t = (double) k * dt;
        double w[3], a[3], b[3];
        body_rate(t, w);
        rotate_inv(q, g_world, a);
        rotate_inv(q, m_world, b);
        for (int i = 0; i < 3; i++) {
            gyr[k].array[i] = (float) ((w[i] + 0.003 * noise()) * rad2deg); /* deg/s */
            acc[k].array[i] = (float) ((a[i] + 0.03 * noise()) / 9.81);     /* g */
            mag[k].array[i] = (float) (b[i] + 0.3 * noise());               /* uT */
            input_sum += gyr[k].array[i] + acc[k].array[i] + mag[k].array[i];
        }
        /* exact step with the mid-interval rate */
        double wm[3];
        body_rate(t + 0.5 * dt, wm);
        const double nrm = sqrt(wm[0] * wm[0] + wm[1] * wm[1] + wm[2] * wm[2]);
        if (nrm > 0.0) {
            const double h = 0.5 * nrm * dt, s = sin(h) / nrm;
            quat e = {cos(h), wm[0] * s, wm[1] * s, wm[2] * s};
            q = qmul(q, e);
            const double qn = sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
            q.w /= qn; q.x /= qn; q.y /= qn; q.z /= qn;
        }
    }

    if (!m9 && !m6) {
        printf("{\"mode\": \"none\", \"samples\": %ld, \"ns_per_update\": 0, \"checksum\": %.9g}\n",
               n, input_sum);
        return 0;
    }

    /* ---- timed passes ---- */
    double best = INFINITY;
    FusionAhrs ahrs;
    for (int p = 0; p < passes; p++) {
        FusionAhrsInitialise(&ahrs);                      /* default settings */
        FusionAhrsSetSamplePeriod(&ahrs, (float) dt);     /* as imufusion set_sample_period */
        const double t0 = now_ns();
        if (m9) {
            for (long k = 0; k < n; k++) FusionAhrsUpdate(&ahrs, gyr[k], acc[k], mag[k]);
        } else {
            for (long k = 0; k < n; k++) FusionAhrsUpdateNoMagnetometer(&ahrs, gyr[k], acc[k]);
        }
        const double el = now_ns() - t0;
        if (el < best) best = el;
    }
    const FusionQuaternion qe = FusionAhrsGetQuaternion(&ahrs);
    const double checksum = qe.element.w + 2.0 * qe.element.x + 3.0 * qe.element.y + 4.0 * qe.element.z;

    if (getenv("FUSION_LOOP_VERBOSE")) { /* tilt error: angle between true and estimated gravity */
        double gt[3];
        rotate_inv(q, (const double[3]) {0, 0, 1}, gt); /* true up in body (last sample's q is one step ahead: negligible) */
        const FusionVector ge = FusionAhrsGetGravity(&ahrs);
        const double e[3] = {ge.axis.x, ge.axis.y, ge.axis.z};
        const double cx = gt[1] * e[2] - gt[2] * e[1], cy = gt[2] * e[0] - gt[0] * e[2], cz = gt[0] * e[1] - gt[1] * e[0];
        const double d = gt[0] * e[0] + gt[1] * e[1] + gt[2] * e[2];
        fprintf(stderr, "final tilt error %.3f deg; q = (%.5f %.5f %.5f %.5f), true q = (%.5f %.5f %.5f %.5f)\n", atan2(sqrt(cx * cx + cy * cy + cz * cz), d) * rad2deg,
                qe.element.w, qe.element.x, qe.element.y, qe.element.z, q.w, q.x, q.y, q.z);
    }
    printf("{\"mode\": \"%s\", \"samples\": %ld, \"ns_per_update\": %.2f, \"checksum\": %.9g}\n",
           mode, n, best / (double) n, checksum);
    free(gyr); free(acc); free(mag);
    return 0;
}
