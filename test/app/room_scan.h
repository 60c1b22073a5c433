/*
 * test/app/room_scan.h - a laser scan ray cast in a room of wall segments,
 * for the odometry check's test and benchmark: 140 deg in 0.35 deg steps
 * (401 rays), 4 m range, Gaussian range noise of 1 cm from a fixed-seed
 * generator. Header-only (static functions).
 */
#ifndef COSLAM_TEST_ROOM_SCAN_H
#define COSLAM_TEST_ROOM_SCAN_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "coslam/pose2.h"

#define DEG (COSLAM_PI / 180.0)
#define N_RAYS 401

typedef struct {
    point2_t a, b;
} seg_t;

typedef struct {
    seg_t s[16];
    int n;
} room_t;

static uint64_t g_rng = 12345u; /* the noise stream; reset it for a repeatable run */

static double gauss(void)
{
    /* Box-Muller on a 64-bit LCG: enough for range noise */
    g_rng = g_rng * 6364136223846793005ULL + 1442695040888963407ULL;
    const double u1 = ((double)(g_rng >> 11) + 0.5) / 9007199254740992.0;
    g_rng = g_rng * 6364136223846793005ULL + 1442695040888963407ULL;
    const double u2 = ((double)(g_rng >> 11) + 0.5) / 9007199254740992.0;
    return sqrt(-2.0 * log(u1)) * cos(2.0 * COSLAM_PI * u2);
}

static void add_box(room_t *r, double x0, double y0, double x1, double y1)
{
    const point2_t c[4] = {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
    for (int i = 0; i < 4; ++i) {
        r->s[r->n].a = c[i];
        r->s[r->n].b = c[(i + 1) % 4];
        r->n++;
    }
}

/* Points of one scan from robot pose p, robot frame, 4 m range. */
static size_t scan(const room_t *room, pose2_t p, point2_t *out)
{
    size_t k = 0;
    for (int i = 0; i < N_RAYS; ++i) {
        const double a = -70.0 * DEG + 140.0 * DEG * (double)i / (double)(N_RAYS - 1);
        const double dx = cos(p.theta + a), dy = sin(p.theta + a);
        double best = INFINITY;
        for (int s = 0; s < room->n; ++s) {
            const double ex = room->s[s].b.x - room->s[s].a.x, ey = room->s[s].b.y - room->s[s].a.y;
            const double den = dx * ey - dy * ex;
            if (fabs(den) < 1e-12) {
                continue;
            }
            const double wx = room->s[s].a.x - p.x, wy = room->s[s].a.y - p.y;
            const double t = (wx * ey - wy * ex) / den;
            const double u = (wx * dy - wy * dx) / den;
            if (t > 0.0 && u >= 0.0 && u <= 1.0 && t < best) {
                best = t;
            }
        }
        if (best < 4.0) {
            const double r = best + 0.01 * gauss();
            out[k].x = r * cos(a);
            out[k].y = r * sin(a);
            ++k;
        }
    }
    return k;
}

#endif /* COSLAM_TEST_ROOM_SCAN_H */
