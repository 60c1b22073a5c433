/* host/cli/bench_args.h - the numeric options and the JSON numbers of the C
 * benches (coslam-bench-*). Header-only.
 *
 * An option's value must be the whole text a whole number inside the
 * option's range: "abc", "5x", "1e3" and values outside are refused with
 * the option, the value and the range said (atoi read them as 0 or 5, and
 * a count of 0 ran and wrote "best of 0 runs" and inf). JSON has no inf or
 * nan: a figure that is not finite (not measured, or a division by zero) is
 * written as null. */
#ifndef COSLAM_BENCH_ARGS_H
#define COSLAM_BENCH_ARGS_H

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

/* The whole of s as a whole number in [lo, hi] into *out (0); else says
 * "<tool>: <opt> '<s>': ..." on stderr and returns -1 (the bench exits 2). */
static inline int bench_arg_long(const char *tool, const char *opt, const char *s, long lo, long hi, long *out)
{
    char *end = NULL;
    errno = 0;
    const long v = strtol(s, &end, 10);
    if (end == s || *end != '\0' || errno == ERANGE) {
        fprintf(stderr, "%s: %s '%.40s': not a whole number (expected one in [%ld, %ld])\n", tool, opt, s, lo, hi);
        return -1;
    }
    if (v < lo || v > hi) {
        fprintf(stderr, "%s: %s %ld outside [%ld, %ld]\n", tool, opt, v, lo, hi);
        return -1;
    }
    *out = v;
    return 0;
}

static inline int bench_arg_int(const char *tool, const char *opt, const char *s, int lo, int hi, int *out)
{
    long v = 0;
    if (bench_arg_long(tool, opt, s, lo, hi, &v) != 0) {
        return -1;
    }
    *out = (int)v;
    return 0;
}

/* v with `decimals` decimals, or null if it is not finite. */
static inline void bench_json_num(FILE *f, double v, int decimals)
{
    if (isfinite(v)) {
        fprintf(f, "%.*f", decimals, v);
    } else {
        fputs("null", f);
    }
}

/* "[v0, v1, ...]", each as bench_json_num. */
static inline void bench_json_array(FILE *f, const double *v, int n, int decimals)
{
    fputc('[', f);
    for (int i = 0; i < n; ++i) {
        if (i > 0) {
            fputs(", ", f);
        }
        bench_json_num(f, v[i], decimals);
    }
    fputc(']', f);
}

/* ", \"key[i]\": v[i]" for each of n fields, each as bench_json_num. */
static inline void bench_json_fields(FILE *f, const char *const *keys, const double *v, int n, int decimals)
{
    for (int i = 0; i < n; ++i) {
        fprintf(f, ", \"%s\": ", keys[i]);
        bench_json_num(f, v[i], decimals);
    }
}

#endif /* COSLAM_BENCH_ARGS_H */
