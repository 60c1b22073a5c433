/* host/cli/bench_report.h - the two report files of a benchmark,
 * <out>/<stem>.md (headed with the build's capacity line) and
 * <out>/<stem>.json. Header-only, for the C benches. */
#ifndef COSLAM_BENCH_REPORT_H
#define COSLAM_BENCH_REPORT_H

#include <stdio.h>

#include "app/profile.h"
#include "checked_file.h"

/* Opens both files (0) or neither (-1, "<tool>: cannot write <path>: <OS
 * reason>" on stderr). */
static inline int bench_report_open(const char *tool, const char *out, const char *stem, FILE **md, FILE **js)
{
    char path[1024];
    *md = *js = NULL;
    for (int k = 0; k < 2; ++k) {
        snprintf(path, sizeof path, "%s/%s.%s", out, stem, k == 0 ? "md" : "json");
        FILE *f = checked_file_open(tool, path);
        if (f == NULL) {
            if (*md != NULL) {
                fclose(*md);
            }
            *md = NULL;
            return -1;
        }
        *(k == 0 ? md : js) = f;
    }
    char prof[192];
    (void)app_profile_format(prof, sizeof prof);
    fprintf(*md, "Built with the capacity %s.\n\n", prof);
    return 0;
}

/* Closes both report files of bench_report_open (or opened alike), checked
 * (checked_file_close): 0, or -1 if either failed (the benches then exit
 * 1). */
static inline int bench_report_close(const char *tool, const char *out, const char *stem, FILE *md, FILE *js)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/%s.md", out, stem);
    const int a = checked_file_close(tool, md, path);
    snprintf(path, sizeof path, "%s/%s.json", out, stem);
    const int b = checked_file_close(tool, js, path);
    return a != 0 || b != 0 ? -1 : 0;
}

#endif /* COSLAM_BENCH_REPORT_H */
