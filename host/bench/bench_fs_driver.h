/*
 * bench_fs_driver.h - the Fast-SLAM scale workload of coslam-bench-fastslam,
 * written once against the public API that the tree implementation and the
 * former flat-array one (host/bench/ref) have in common. Included by
 * bench_fs_new.c and bench_fs_ref.c, each compiled against its own
 * fastslam.h; BENCH_FS_RUN names the entry point.
 *
 * World: M landmarks on a jittered grid (spacing 1.5 m, +-0.45 m), 4 marker
 * classes, already mapped (every particle holds all M, shared as after a
 * resampling: added to particle 0, then resampled); the robot drives a circle
 * of radius 2.5 m around the centre of the field at 0.25 m/s with noisy
 * odometry (10 Hz) and range-bearing sightings (5 Hz, default sensor: 5 m,
 * 50 deg, p_detect 0.9), unknown association. The landmarks in reach are
 * about the same for every M; only the map size changes.
 * Timed: fastslam_predict + fastslam_update + (when the ESS fell below N/2)
 * fastslam_resample, per step; resampling also on its own.
 */
#include <math.h>
#include <string.h>
#include <time.h>

#include "bench_fs.h"
#include "coslam/fastslam.h"
#include "coslam/rng.h"

static double bench_now_us(void)
{
    struct timespec ts;
    clock_gettime(bench_fs_cpu_clock ? CLOCK_THREAD_CPUTIME_ID : CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e6 + (double)ts.tv_nsec * 1e-3;
}

static fastslam_t g_bench_fs;
static point2_t g_bench_lm[BENCH_FS_MAX_M];
static uint8_t g_bench_sig[BENCH_FS_MAX_M];

int BENCH_FS_RUN(const bench_fs_case_t *bc, bench_fs_result_t *res)
{
    fastslam_t *fs = &g_bench_fs;
    memset(res, 0, sizeof *res);
    if (bc->n_landmarks > BENCH_FS_MAX_M || bc->n_landmarks > COSLAM_MAX_LANDMARKS ||
        bc->n_particles > COSLAM_MAX_PARTICLES) {
        return -1;
    }
    rng_t world;
    rng_seed(&world, bc->seed);
    const int m = bc->n_landmarks;
    const double spacing = 1.5;
    const int side = (int)ceil(sqrt((double)m));
    const double half = 0.5 * spacing * side;
    for (int j = 0; j < m; ++j) {
        g_bench_lm[j].x = spacing * (j % side + 0.5) - half + 0.3 * spacing * (2.0 * rng_uniform(&world) - 1.0);
        g_bench_lm[j].y = spacing * (j / side + 0.5) - half + 0.3 * spacing * (2.0 * rng_uniform(&world) - 1.0);
        g_bench_sig[j] = (uint8_t)rng_below(&world, 4);
    }
    fastslam_config_t cfg = fastslam_config_default();
    cfg.n_particles = (uint16_t)bc->n_particles;
    cfg.proposal = bc->fs2 ? FASTSLAM_PROPOSAL_OPTIMAL : FASTSLAM_PROPOSAL_MOTION;
    cfg.resample_ess_fraction = 1e-12; /* resampled below, timed on its own */
    const slam_params_t *sp = &cfg.slam;
    const double radius = 2.5;
    const double v = 0.25;
    const double dt = 0.1;
    pose2_t truth = {radius, 0.0, 0.5 * COSLAM_PI};
    if (fastslam_init(fs, &cfg, truth, bc->seed + 1U) != COSLAM_OK) {
        return -1;
    }
    /* the mapped field: particle 0, then shared by resampling */
    for (int j = 0; j < m; ++j) {
        landmark_t lm;
        memset(&lm, 0, sizeof lm);
        lm.mean.x = g_bench_lm[j].x + 0.03 * rng_gauss(&world);
        lm.mean.y = g_bench_lm[j].y + 0.03 * rng_gauss(&world);
        lm.cov = cov2_make(0.03 * 0.03, 0.0, 0.03 * 0.03);
        lm.id = fastslam_new_id(fs);
        lm.exist = sp->exist_max;
        lm.n_obs = 10;
        lm.src_mask = 1;
        lm.signature = g_bench_sig[j];
        lm.confirmed_once = 1;
        if (fastslam_particle_add(fs, 0, &lm) != COSLAM_OK) {
            return -1;
        }
    }
    for (int k = 1; k < bc->n_particles; ++k) {
        fs->particles[k].log_w = -1000.0;
    }
    fastslam_resample(fs);
    const double sd_r = sqrt(sp->noise.range_var_m2);
    const double sd_b = sqrt(sp->noise.bearing_var_rad2);
    double t_sum = 0.0;
    double t_update = 0.0;
    double rs_sum = 0.0;
    long n_sightings = 0;
    int frames = 0;
    for (int step = 0; step < bc->steps; ++step) {
        /* truth and noisy odometry */
        const odo_increment_t u_true = {v * dt, 0.0, v * dt / radius};
        truth = motion_apply(truth, u_true);
        const double travel = v * dt;
        odo_increment_t u = u_true;
        u.dx += sqrt(sp->noise.odo_xy_var_m2_per_m * travel) * rng_gauss(&world);
        u.dy += sqrt(sp->noise.odo_xy_var_m2_per_m * travel) * rng_gauss(&world);
        u.dtheta += sqrt(sp->noise.odo_theta_var_rad2_per_m * travel) * rng_gauss(&world);
        sighting_t z[COSLAM_MAX_SIGHTINGS];
        int nz = 0;
        const int frame = step % 2 == 1;
        if (frame) {
            for (int j = 0; j < m && nz < COSLAM_MAX_SIGHTINGS; ++j) {
                const point2_t rel = pose2_apply_inverse(truth, g_bench_lm[j]);
                const double r = hypot(rel.x, rel.y);
                const double b = atan2(rel.y, rel.x);
                if (r < sp->sensor_min_range_m || r > sp->sensor_max_range_m || fabs(b) > 0.5 * sp->sensor_fov_rad ||
                    rng_uniform(&world) > 0.9) {
                    continue;
                }
                z[nz].range_m = r + sd_r * rng_gauss(&world);
                z[nz].bearing_rad = angle_wrap(b + sd_b * rng_gauss(&world));
                z[nz].signature = g_bench_sig[j];
                ++nz;
            }
        }
        const double t0 = bench_now_us();
        (void)fastslam_predict(fs, u);
        double t_rs = 0.0;
        if (frame) {
            const double tu = bench_now_us();
            (void)fastslam_update(fs, z, nz);
            t_update += bench_now_us() - tu;
            if (fs->last_ess < 0.5 * (double)bc->n_particles) {
                const double t1 = bench_now_us();
                fastslam_resample(fs);
                t_rs = bench_now_us() - t1;
                rs_sum += t_rs;
                res->resamples++;
                res->resample_us_max = t_rs > res->resample_us_max ? t_rs : res->resample_us_max;
            }
            n_sightings += nz;
            ++frames;
        }
        const double t_step = bench_now_us() - t0;
        t_sum += t_step;
        res->step_us_max = t_step > res->step_us_max ? t_step : res->step_us_max;
    }
    res->step_us_mean = t_sum / bc->steps;
    res->update_us_mean = frames > 0 ? t_update / frames : 0.0;
    res->resample_us_mean = res->resamples > 0 ? rs_sum / res->resamples : 0.0;
    res->sightings_per_frame = frames > 0 ? (double)n_sightings / frames : 0.0;
    res->n_lm_end = fs->particles[0].n_lm;
    pose2_t est;
    cov3_t cov;
    fastslam_pose_estimate(fs, &est, &cov);
    res->final_pos_err_m = hypot(est.x - truth.x, est.y - truth.y);
    return 0;
}
