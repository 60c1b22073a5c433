/* host/cli/bench_report.h - the two report files of a benchmark,
 * <out>/<stem>.md (headed with the build's capacity line) and
 * <out>/<stem>.json. Header-only, for the C benches. */
#ifndef COSLAM_BENCH_REPORT_H
#define COSLAM_BENCH_REPORT_H

#include <stdio.h>

#include "app/profile.h"

/* Opens both files (0) or neither (-1, the reason on stderr, `tool` named). */
static inline int bench_report_open(const char *tool, const char *out, const char *stem, FILE **md, FILE **js)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/%s.md", out, stem);
    *md = fopen(path, "w");
    snprintf(path, sizeof path, "%s/%s.json", out, stem);
    *js = fopen(path, "w");
    if (*md == NULL || *js == NULL) {
        fprintf(stderr, "%s: cannot write %s.md/.json into %s\n", tool, stem, out);
        if (*md != NULL) {
            fclose(*md);
        }
        if (*js != NULL) {
            fclose(*js);
        }
        *md = *js = NULL;
        return -1;
    }
    char prof[192];
    (void)app_profile_format(prof, sizeof prof);
    fprintf(*md, "Built with the capacity %s.\n\n", prof);
    return 0;
}

#endif /* COSLAM_BENCH_REPORT_H */
