/* The scale workload on the former Fast-SLAM (a flat landmark array per
 * particle, whole-map copies in resampling): host/bench/ref, symbols renamed
 * by bench_fs_ref_names.h so that both live in one benchmark binary. */
#define _POSIX_C_SOURCE 200809L
#define BENCH_FS_RUN bench_fs_ref_run
#include "bench_fs_driver.h"
