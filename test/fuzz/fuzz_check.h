/*
 * test/fuzz/fuzz_check.h - the one way a fuzz target reports a broken
 * property: a message on stderr and abort(), which libFuzzer records as a
 * crash with the input that caused it. C and C++.
 */
#ifndef COSLAM_FUZZ_CHECK_H
#define COSLAM_FUZZ_CHECK_H

#include <stdio.h>
#include <stdlib.h>

static inline void fuzz_require(int ok, const char *what)
{
    if (!ok) {
        fprintf(stderr, "property violated: %s\n", what);
        abort();
    }
}

#endif
