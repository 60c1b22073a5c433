/* Small helpers shared by the cmocka core tests. */
#ifndef COSLAM_TEST_UTIL_H
#define COSLAM_TEST_UTIL_H

#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <cmocka.h>

/* assert |a - b| <= tol, printing both values on failure */
#define ASSERT_NEAR(a, b, tol)                                                                      \
    do {                                                                                            \
        const double a_ = (a);                                                                      \
        const double b_ = (b);                                                                      \
        if (!(fabs(a_ - b_) <= (tol))) {                                                            \
            print_error("%s = %.12g, %s = %.12g, |diff| %.3g > %.3g\n", #a, a_, #b, b_, fabs(a_ - b_), \
                        (double)(tol));                                                             \
            fail();                                                                                 \
        }                                                                                           \
    } while (0)

#define ASSERT_TRUE_MSG(cond, ...)     \
    do {                               \
        if (!(cond)) {                 \
            print_error(__VA_ARGS__);  \
            fail_msg("%s", #cond);     \
        }                              \
    } while (0)

#endif
