/* The scale workload on the core's Fast-SLAM (shared landmark tree). */
#define _POSIX_C_SOURCE 200809L
#define BENCH_FS_RUN bench_fs_new_run
#include "bench_fs_driver.h"
