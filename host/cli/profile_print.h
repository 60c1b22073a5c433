/* host/cli/profile_print.h - the start-up line of the C host tools (the
 * benches, coslam-eval-worlds, coslam-demo): "<tool>: profile ..." from
 * app/profile.h, the same line the C++ tools print (profile_json.hpp). */
#ifndef COSLAM_PROFILE_PRINT_H
#define COSLAM_PROFILE_PRINT_H

#include <stdio.h>

#include "app/profile.h"

static inline void profile_print(FILE *f, const char *tool)
{
    char line[192];
    (void)app_profile_format(line, sizeof line);
    fprintf(f, "%s: %s\n", tool, line);
    (void)fflush(f); /* seen even if the tool is stopped early */
}

#endif /* COSLAM_PROFILE_PRINT_H */
