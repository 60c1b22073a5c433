/*
 * app/slam_params_ini.h - the one table of the [slam] settings: every field
 * of slam_params_t (coslam/slam_params.h) by its C name, with its type and
 * its domain, and the one parser of their values.
 *
 * Every entry point that reads a parameter file uses this table for its
 * [slam] section: coslam-replay (host/replay/replay_config.cpp) and
 * coslam-robot (firmware/port/linux/robot_config.c). So a [slam] section
 * means the same thing to both, key for key and bit for bit (the test
 * test/port_linux/test_robot_slam_keys.cpp checks it across the two tools).
 *
 * Values: a decimal number as strtod(3) reads it (C locale), the whole text
 * (no trailing characters; the INI reader has already stripped blanks and
 * inline comments), finite. Float fields are set from the double by a
 * conversion to float (round to nearest). Each key has a domain [min, max]
 * (min excluded where min_open is set) taken from slam_params_validate();
 * the rules that tie two keys together (max range > min range,
 * new_landmark_chi2 >= gate_chi2, exist_init <= exist_confirm <= exist_max)
 * are checked on the whole struct by slam_params_ini_cross_check().
 *
 * No heap, no globals with state, no I/O: the table is const data. Messages
 * go into caller buffers (truncated to their capacity, always terminated).
 */
#ifndef COSLAM_APP_SLAM_PARAMS_INI_H
#define COSLAM_APP_SLAM_PARAMS_INI_H

#include <stddef.h>
#include <stdint.h>

#include "coslam/slam_params.h"
#include "coslam/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Storage type of a field. */
typedef enum {
    SLAM_PARAMS_INI_DOUBLE = 1,
    SLAM_PARAMS_INI_FLOAT = 2,
} slam_params_ini_type_t;

/** One [slam] key. */
typedef struct {
    const char *name;             /**< INI key = the C field name (noise fields without "noise.") */
    size_t offset;                /**< offsetof(slam_params_t, field) */
    slam_params_ini_type_t type;
    double min;                   /**< domain: min <= v (min < v with min_open) ... */
    double max;                   /**< ... and v <= max */
    uint8_t min_open;             /**< 1: the minimum itself is outside the domain */
} slam_params_ini_key_t;

/** Number of keys (every field of slam_params_t). O(1). */
size_t slam_params_ini_count(void);

/** Key i (0 <= i < count), in declaration order of slam_params_t; NULL
 *  beyond. O(1). */
const slam_params_ini_key_t *slam_params_ini_key(size_t i);

/** The key named `name`, or NULL. O(count). */
const slam_params_ini_key_t *slam_params_ini_find(const char *name);

/** Index of a key in the table (for per-key bookkeeping such as the line it
 *  was read from). O(1). */
size_t slam_params_ini_index(const slam_params_ini_key_t *k);

/**
 * Parse a number the way every settings file of the project does: strtod
 * over the whole text, finite, no ERANGE. Returns COSLAM_OK (*out set) or
 * COSLAM_E_NUMERIC (not a finite number; *out untouched); COSLAM_E_ARG for
 * NULL. O(length).
 */
coslam_status_t slam_params_ini_parse_number(const char *text, double *out);

/**
 * Set field `key` of *p from `text`. Returns:
 *   COSLAM_OK            set;
 *   COSLAM_E_UNSUPPORTED no such key (msg: "unknown key 'k' in [slam]");
 *   COSLAM_E_NUMERIC     not a finite number (msg: "not a finite number: 't'");
 *   COSLAM_E_ARG         outside the key's domain (msg: "t is outside its
 *                        domain (min, max]"), or NULL p / key / text.
 * *p is unchanged on any error. msg (may be NULL when msg_cap is 0)
 * receives the reason, without file, line or section prefix: each caller
 * adds its own. O(count + length).
 */
coslam_status_t slam_params_ini_set(slam_params_t *p, const char *key, const char *text, char *msg, size_t msg_cap);

/** The value of key k in *p, as a double (float fields widened exactly). O(1). */
double slam_params_ini_get(const slam_params_t *p, const slam_params_ini_key_t *k);

/**
 * The rules between keys, on the whole struct: COSLAM_OK, or COSLAM_E_ARG
 * with the two keys of the first broken rule in *key and *other (either may
 * be NULL; *key is sensor_max_range_m, new_landmark_chi2, exist_confirm or
 * exist_max, *other the key it is compared with) and the rule in msg. With
 * these rules and every key inside its domain, slam_params_validate()
 * holds. O(1).
 */
coslam_status_t slam_params_ini_cross_check(const slam_params_t *p, const slam_params_ini_key_t **key,
                                            const slam_params_ini_key_t **other, char *msg, size_t msg_cap);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_APP_SLAM_PARAMS_INI_H */
