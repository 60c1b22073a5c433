/* host/cli/profile_print.h - the start-up line of the C host tools (the
 * benches, coslam-eval-worlds, coslam-demo): "<tool>: profile ..." from
 * app/profile.h, the same line the C++ tools print (profile_json.hpp). */
#ifndef COSLAM_PROFILE_PRINT_H
#define COSLAM_PROFILE_PRINT_H

#include <stdio.h>

#include "app/profile.h"
#include "stdout_check.h"

static inline void profile_print(FILE *f, const char *tool)
{
    char line[192];
    (void)app_profile_format(line, sizeof line);
    fprintf(f, "%s: %s\n", tool, line);
    /* seen even if the tool is stopped early; on stdout a failure's reason
     * kept for the tool's final check (stdout_check.h) */
    (void)(f == stdout ? stdout_check_flush() : fflush(f));
}

#endif /* COSLAM_PROFILE_PRINT_H */
