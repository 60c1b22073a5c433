/* bench_fs.h - interface between coslam-bench-fastslam and its two builds of
 * the same workload (bench_fs_driver.h): the shared-tree Fast-SLAM of the
 * core (bench_fs_new.c) and the former flat-array one (bench_fs_ref.c). */
#ifndef COSLAM_BENCH_FS_H
#define COSLAM_BENCH_FS_H

#include <stdint.h>

#define BENCH_FS_MAX_M 2048

typedef struct {
    int n_particles;
    int n_landmarks;
    int steps;        /* control steps at 10 Hz; an update every second one */
    uint64_t seed;
    int fs2;          /* 1: Fast-SLAM 2.0, 0: 1.0 */
} bench_fs_case_t;

typedef struct {
    double step_us_mean;      /* predict + update + resampling, per control step */
    double step_us_max;
    double update_us_mean;    /* fastslam_update alone, per camera frame */
    double resample_us_mean;  /* fastslam_resample alone */
    double resample_us_max;
    int resamples;
    double sightings_per_frame;
    double n_lm_end;
    double final_pos_err_m;
} bench_fs_result_t;

/* 1: time with the thread's CPU clock (robust on a shared machine),
 * 0: wall clock (default). Defined in coslam_bench_fastslam.c. */
extern int bench_fs_cpu_clock;

int bench_fs_new_run(const bench_fs_case_t *c, bench_fs_result_t *r);
int bench_fs_ref_run(const bench_fs_case_t *c, bench_fs_result_t *r);

#endif
