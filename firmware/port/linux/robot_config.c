/* coslam-robot settings: key table, INI reader (libinih), printer (robot_config.h). */
#include "robot_config.h"

#include <errno.h>
#include <fcntl.h>
#include <ini.h>
#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <sys/stat.h>
#include <string.h>
#include <unistd.h>

#include "app/slam_params_ini.h"

/* snprintf that may truncate on purpose (messages, labels): always terminated. */
__attribute__((format(printf, 3, 4))) static void put_text(char *dst, size_t cap, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    (void)vsnprintf(dst, cap, fmt, ap);
    va_end(ap);
}

typedef enum {
    K_BOOL = 1, /* uint8_t 0/1: 0 1 true false yes no on off */
    K_U8,
    K_U16,
    K_U32,
    K_U64,
    K_F64,
    K_US,       /* seconds in the file, uint32_t microseconds in the struct */
    K_STR,      /* char[ROBOT_CONFIG_PATH_MAX + 1] */
    K_CUSTOM,
} key_type_t;

typedef struct cfg_key cfg_key_t;

/* A custom key: parse into cfg (COSLAM_OK or COSLAM_E_ARG with msg), print. */
typedef coslam_status_t (*key_parse_fn)(robot_config_t *c, const char *value, char *msg, size_t cap);
typedef void (*key_print_fn)(const robot_config_t *c, FILE *out);

struct cfg_key {
    const char *section;
    const char *name;
    key_type_t type;
    size_t offset;     /* into robot_config_t */
    double min;        /* domain [min, max] (min excluded with min_open) */
    double max;
    int min_open;
    key_parse_fn parse;
    key_print_fn print;
};

#define OFF_(f) offsetof(robot_config_t, f)

/* ---- custom keys --------------------------------------------------------- */

static coslam_status_t parse_int(const char *v, long lo, long hi, long *out, char *msg, size_t cap)
{
    double d = 0.0;
    if (slam_params_ini_parse_number(v, &d) != COSLAM_OK || d != floor(d) || d < (double)lo || d > (double)hi) {
        put_text(msg, cap, "expected an integer in [%ld, %ld], got '%s'", lo, hi, v);
        return COSLAM_E_ARG;
    }
    *out = (long)d;
    return COSLAM_OK;
}

/* Comma-separated integers in [lo, hi], at most max_n (an empty value: none). */
static coslam_status_t parse_list(const char *v, long lo, long hi, long *out, int max_n, int *n, char *msg,
                                  size_t cap)
{
    *n = 0;
    char buf[ROBOT_CONFIG_PATH_MAX + 1u];
    if (strlen(v) > ROBOT_CONFIG_PATH_MAX) {
        put_text(msg, cap, "list too long");
        return COSLAM_E_ARG;
    }
    put_text(buf, sizeof buf, "%s", v);
    char *p = buf;
    while (*p != '\0') {
        char *comma = strchr(p, ',');
        if (comma != NULL) {
            *comma = '\0';
        }
        while (*p == ' ' || *p == '\t') {
            ++p;
        }
        size_t len = strlen(p);
        while (len > 0U && (p[len - 1U] == ' ' || p[len - 1U] == '\t')) {
            p[--len] = '\0';
        }
        if (*n >= max_n) {
            put_text(msg, cap, "at most %d entries", max_n);
            return COSLAM_E_ARG;
        }
        if (parse_int(p, lo, hi, &out[*n], msg, cap) != COSLAM_OK) {
            return COSLAM_E_ARG;
        }
        (*n)++;
        if (comma == NULL) {
            break;
        }
        p = comma + 1;
    }
    return COSLAM_OK;
}

static coslam_status_t parse_profile(robot_config_t *c, const char *v, char *msg, size_t cap)
{
    (void)c;
    if (strcmp(v, COSLAM_PROFILE_NAME) != 0) {
        put_text(msg, cap, "this binary is built for the '%s' capacity profile, not '%s'",
                       COSLAM_PROFILE_NAME, v);
        return COSLAM_E_ARG;
    }
    return COSLAM_OK;
}

static void print_profile(const robot_config_t *c, FILE *out)
{
    (void)c;
    fprintf(out, "%s", COSLAM_PROFILE_NAME);
}

static coslam_status_t parse_filter_type(robot_config_t *c, const char *v, char *msg, size_t cap)
{
    if (strcmp(v, "fastslam1") == 0 || strcmp(v, "fs1") == 0) {
        c->node.filter.kind = SLAM_FILTER_FASTSLAM1;
    } else if (strcmp(v, "fastslam2") == 0 || strcmp(v, "fs2") == 0) {
        c->node.filter.kind = SLAM_FILTER_FASTSLAM2;
    } else if (strcmp(v, "ekf") == 0 || strcmp(v, "ekfslam") == 0) {
        c->node.filter.kind = SLAM_FILTER_EKF;
    } else {
        put_text(msg, cap, "unknown filter '%s' (expected fastslam1, fastslam2 or ekf)", v);
        return COSLAM_E_ARG;
    }
    return COSLAM_OK;
}

static void print_filter_type(const robot_config_t *c, FILE *out)
{
    fprintf(out, "%s", slam_filter_kind_name(c->node.filter.kind));
}

static coslam_status_t parse_assoc(robot_config_t *c, const char *v, char *msg, size_t cap)
{
    if (strcmp(v, "jcbb") == 0) {
        c->node.filter.assoc = EKFSLAM_ASSOC_JCBB;
    } else if (strcmp(v, "nn") == 0) {
        c->node.filter.assoc = EKFSLAM_ASSOC_NN;
    } else {
        put_text(msg, cap, "expected jcbb or nn, got '%s'", v);
        return COSLAM_E_ARG;
    }
    return COSLAM_OK;
}

static void print_assoc(const robot_config_t *c, FILE *out)
{
    fprintf(out, "%s", c->node.filter.assoc == EKFSLAM_ASSOC_NN ? "nn" : "jcbb");
}

static coslam_status_t parse_node_ids(robot_config_t *c, const char *v, char *msg, size_t cap)
{
    long ids[OMNI_WHEELS];
    int n = 0;
    if (parse_list(v, 1, 127, ids, OMNI_WHEELS, &n, msg, cap) != COSLAM_OK) {
        return COSLAM_E_ARG;
    }
    if (n != OMNI_WHEELS) {
        put_text(msg, cap, "expected %d CANopen node ids (1..127), got %d", OMNI_WHEELS, n);
        return COSLAM_E_ARG;
    }
    for (int k = 0; k < OMNI_WHEELS; ++k) {
        for (int j = 0; j < k; ++j) {
            if (ids[j] == ids[k]) {
                put_text(msg, cap, "node id %ld appears twice", ids[k]);
                return COSLAM_E_ARG;
            }
        }
    }
    for (int k = 0; k < OMNI_WHEELS; ++k) {
        c->node.drive.node_id[k] = (uint8_t)ids[k];
    }
    return COSLAM_OK;
}

static coslam_status_t parse_loss_action(robot_config_t *c, const char *v, char *msg, size_t cap)
{
    static const char *const names[] = {"fault", "disable_voltage", "quick_stop"}; /* 0x6007 1, 2, 3 */
    for (int k = 0; k < 3; ++k) {
        if (strcmp(v, names[k]) == 0) {
            c->node.drive.drive.master_loss_action = (int16_t)(CIA402_ABORT_FAULT + k);
            return COSLAM_OK;
        }
    }
    put_text(msg, cap, "expected quick_stop, disable_voltage or fault");
    return COSLAM_E_ARG;
}

static void print_loss_action(const robot_config_t *c, FILE *out)
{
    switch (c->node.drive.drive.master_loss_action) {
    case CIA402_ABORT_FAULT: fprintf(out, "fault"); break;
    case CIA402_ABORT_DISABLE_VOLTAGE: fprintf(out, "disable_voltage"); break;
    default: fprintf(out, "quick_stop"); break;
    }
}

static void print_node_ids(const robot_config_t *c, FILE *out)
{
    for (int k = 0; k < OMNI_WHEELS; ++k) {
        fprintf(out, "%s%u", k > 0 ? ", " : "", (unsigned)c->node.drive.node_id[k]);
    }
}

static coslam_status_t parse_bumpers(robot_config_t *c, const char *v, char *msg, size_t cap)
{
    long lines[COSLAM_MAX_BUMPERS];
    int n = 0;
    if (parse_list(v, 0, 1023, lines, COSLAM_MAX_BUMPERS, &n, msg, cap) != COSLAM_OK) {
        return COSLAM_E_ARG;
    }
    c->node.gpio.n_bumpers = (uint8_t)n;
    for (int k = 0; k < n; ++k) {
        c->node.gpio.bumpers[k].line = (uint32_t)lines[k];
    }
    return COSLAM_OK;
}

static void print_bumpers(const robot_config_t *c, FILE *out)
{
    for (unsigned k = 0; k < c->node.gpio.n_bumpers; ++k) {
        fprintf(out, "%s%u", k > 0 ? ", " : "", (unsigned)c->node.gpio.bumpers[k].line);
    }
}

static coslam_status_t parse_bumper_low(robot_config_t *c, const char *v, char *msg, size_t cap);
static void print_bumper_low(const robot_config_t *c, FILE *out)
{
    fprintf(out, "%d", c->node.gpio.bumpers[0].active_low ? 1 : 0);
}

static coslam_status_t parse_leds(robot_config_t *c, const char *v, char *msg, size_t cap)
{
    long lines[COSLAM_MAX_STATUS_LEDS];
    int n = 0;
    if (parse_list(v, 0, 1023, lines, COSLAM_MAX_STATUS_LEDS, &n, msg, cap) != COSLAM_OK) {
        return COSLAM_E_ARG;
    }
    c->node.gpio.n_leds = (uint8_t)n;
    for (int k = 0; k < n; ++k) {
        c->node.gpio.leds[k].line = (uint32_t)lines[k];
        c->node.gpio.leds[k].active_low = false;
    }
    return COSLAM_OK;
}

static void print_leds(const robot_config_t *c, FILE *out)
{
    for (unsigned k = 0; k < c->node.gpio.n_leds; ++k) {
        fprintf(out, "%s%u", k > 0 ? ", " : "", (unsigned)c->node.gpio.leds[k].line);
    }
}

static coslam_status_t parse_estop(robot_config_t *c, const char *v, char *msg, size_t cap)
{
    long line = 0;
    if (parse_int(v, -1, 1023, &line, msg, cap) != COSLAM_OK) {
        return COSLAM_E_ARG;
    }
    c->node.gpio.has_estop = line >= 0;
    c->node.gpio.estop.line = line >= 0 ? (uint32_t)line : 0U;
    return COSLAM_OK;
}

static void print_estop(const robot_config_t *c, FILE *out)
{
    fprintf(out, "%ld", c->node.gpio.has_estop ? (long)c->node.gpio.estop.line : -1L);
}

static coslam_status_t parse_bool_text(const char *v, uint8_t *out, char *msg, size_t cap)
{
    if (strcmp(v, "1") == 0 || strcmp(v, "true") == 0 || strcmp(v, "yes") == 0 || strcmp(v, "on") == 0) {
        *out = 1U;
    } else if (strcmp(v, "0") == 0 || strcmp(v, "false") == 0 || strcmp(v, "no") == 0 || strcmp(v, "off") == 0) {
        *out = 0U;
    } else {
        put_text(msg, cap, "expected a boolean (0/1, true/false, yes/no, on/off), got '%s'", v);
        return COSLAM_E_ARG;
    }
    return COSLAM_OK;
}

static coslam_status_t parse_bumper_low(robot_config_t *c, const char *v, char *msg, size_t cap)
{
    uint8_t b = 0U;
    if (parse_bool_text(v, &b, msg, cap) != COSLAM_OK) {
        return COSLAM_E_ARG;
    }
    for (unsigned k = 0; k < COSLAM_MAX_BUMPERS; ++k) {
        c->node.gpio.bumpers[k].active_low = b != 0U;
    }
    return COSLAM_OK;
}

static coslam_status_t parse_estop_low(robot_config_t *c, const char *v, char *msg, size_t cap)
{
    uint8_t b = 0U;
    if (parse_bool_text(v, &b, msg, cap) != COSLAM_OK) {
        return COSLAM_E_ARG;
    }
    c->node.gpio.estop.active_low = b != 0U;
    return COSLAM_OK;
}

static void print_estop_low(const robot_config_t *c, FILE *out)
{
    fprintf(out, "%d", c->node.gpio.estop.active_low ? 1 : 0);
}

/* [link] peers: comma-separated addresses that go into Cyclone's XML, so
 * only host names, IPv4 and [IPv6] characters (as hal_link_dds_open checks
 * again). Stored normalised ("a, b") so that printing reads back the same. */
static int peer_char_ok(char ch)
{
    return (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') || ch == '.' ||
           ch == ':' || ch == '-' || ch == '_' || ch == '[' || ch == ']';
}

/* libinih reads lines of at most INI_MAX_LINE - 2 characters (plus the
 * newline and the NUL); robot_config_print writes "key = value". A value is
 * kept only if that line fits, so that every configuration printed reads
 * back (found by fuzzing, docs/fuzzing.md). */
static int fits_line(const char *key, size_t value_len)
{
    return strlen(key) + 3U + value_len <= (size_t)(INI_MAX_LINE - 2);
}

static coslam_status_t parse_peers(robot_config_t *c, const char *v, char *msg, size_t cap)
{
    char out[ROBOT_CONFIG_PATH_MAX + 1u];
    out[0] = '\0';
    size_t len = 0;
    unsigned n = 0;
    const char *p = v;
    while (*p != '\0') {
        while (*p == ' ' || *p == '\t') {
            ++p;
        }
        const char *start = p;
        while (*p != '\0' && *p != ',') {
            ++p;
        }
        const char *end = p;
        while (end > start && (end[-1] == ' ' || end[-1] == '\t')) {
            --end;
        }
        if (end == start) {
            put_text(msg, cap, "empty peer address in '%s'", v);
            return COSLAM_E_ARG;
        }
        for (const char *q = start; q < end; ++q) {
            if (!peer_char_ok(*q)) {
                put_text(msg, cap, "peer address '%.*s' has a character other than [A-Za-z0-9.:_-] and [ ]",
                         (int)(end - start), start);
                return COSLAM_E_ARG;
            }
        }
        if (++n > ROBOT_CONFIG_MAX_PEERS) {
            put_text(msg, cap, "at most %u peers", ROBOT_CONFIG_MAX_PEERS);
            return COSLAM_E_ARG;
        }
        const size_t add = (size_t)(end - start) + (n > 1U ? 2U : 0U);
        if (len + add > ROBOT_CONFIG_PATH_MAX || !fits_line("peers", len + add)) {
            put_text(msg, cap, "list too long (written back as 'a, b, ...' it must fit in one line of %d characters)",
                     INI_MAX_LINE - 2);
            return COSLAM_E_ARG;
        }
        if (n > 1U) {
            memcpy(out + len, ", ", 2U);
            len += 2U;
        }
        memcpy(out + len, start, (size_t)(end - start));
        len += (size_t)(end - start);
        out[len] = '\0';
        if (*p == ',') {
            ++p;
            if (*p == '\0') {
                put_text(msg, cap, "empty peer address after the last comma");
                return COSLAM_E_ARG;
            }
        }
    }
    put_text(c->link_peers, sizeof c->link_peers, "%s", out);
    return COSLAM_OK;
}

static void print_peers(const robot_config_t *c, FILE *out)
{
    fprintf(out, "%s", c->link_peers);
}

/* [link] topic: a DDS topic name (ROS 2 style: letters, digits, _ and /). */
static coslam_status_t parse_topic(robot_config_t *c, const char *v, char *msg, size_t cap)
{
    if (*v == '\0') {
        put_text(msg, cap, "empty topic (the default is %s)", ROBOT_CONFIG_DEFAULT_TOPIC);
        return COSLAM_E_ARG;
    }
    for (const char *q = v; *q != '\0'; ++q) {
        const char ch = *q;
        if (!((ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') || ch == '_' ||
              ch == '/')) {
            put_text(msg, cap, "topic '%s' has a character other than [A-Za-z0-9_/]", v);
            return COSLAM_E_ARG;
        }
    }
    if (strlen(v) > ROBOT_CONFIG_PATH_MAX) {
        put_text(msg, cap, "longer than %u characters", ROBOT_CONFIG_PATH_MAX);
        return COSLAM_E_ARG;
    }
    put_text(c->link_topic, sizeof c->link_topic, "%s", v);
    return COSLAM_OK;
}

static void print_topic(const robot_config_t *c, FILE *out)
{
    fprintf(out, "%s", c->link_topic);
}

/* ---- the table ----------------------------------------------------------- */

#define INF_ HUGE_VAL
#define B_(sec, name, field) {sec, name, K_BOOL, OFF_(field), 0.0, 1.0, 0, NULL, NULL}
#define N_(sec, name, type, field, lo, hi) {sec, name, type, OFF_(field), lo, hi, 0, NULL, NULL}
#define NO_(sec, name, type, field, lo, hi) {sec, name, type, OFF_(field), lo, hi, 1, NULL, NULL}
#define S_(sec, name, field) {sec, name, K_STR, OFF_(field), 0.0, 0.0, 0, NULL, NULL}
#define C_(sec, name, parse, print) {sec, name, K_CUSTOM, 0U, 0.0, 0.0, 0, parse, print}

static const cfg_key_t keys[] = {
    N_("robot", "id", K_U8, robot_id, 0, COSLAM_MAX_ROBOTS - 1),
    N_("robot", "fleet_size", K_U8, fleet_size, 2, COSLAM_MAX_ROBOTS),
    C_("robot", "profile", parse_profile, print_profile),
    N_("robot", "step_period_s", K_US, step_period_us, 0.001, 1.0),
    N_("robot", "status_period_s", K_F64, status_period_s, 0.0, 86400.0),
    N_("robot", "snapshot_period_s", K_F64, snapshot_period_s, 0.0, 86400.0),
    N_("robot", "retry_period_s", K_F64, retry_period_s, 0.1, 3600.0),

    S_("laser", "device", laser_device),
    N_("laser", "baud", K_U32, laser_baud, 1200, 4000000),
    N_("laser", "reply_timeout_s", K_US, node.urg.reply_timeout_us, 0.01, 10.0),
    N_("laser", "lost_timeout_s", K_US, node.laser_lost_us, 0.0, 60.0),
    N_("laser", "blind_max_turn_radps", K_F64, node.blind_max_turn_radps, 0.0, 3.0),
    NO_("laser", "fov_rad", K_F64, node.laser_fov_rad, 0.0, 4.2),
    N_("laser", "mount_x_m", K_F64, node.laser_in_robot.x, -2.0, 2.0),
    N_("laser", "mount_y_m", K_F64, node.laser_in_robot.y, -2.0, 2.0),
    N_("laser", "mount_theta_rad", K_F64, node.laser_in_robot.theta, -3.2, 3.2),

    S_("can", "interface", can_interface),
    C_("can", "node_ids", parse_node_ids, print_node_ids),
    N_("can", "master_node_id", K_U8, node.drive.drive.master_node_id, 0, 127),
    N_("can", "master_heartbeat_period_ms", K_U16, node.drive.master_heartbeat_period_ms, 1, 10000),
    N_("can", "watchdog_timeout_ms", K_U16, node.drive.drive.master_timeout_ms, 1, 60000),
    C_("can", "watchdog_action", parse_loss_action, print_loss_action),

    S_("gpio", "chip", gpio_chip),
    B_("gpio", "required", gpio_required),
    C_("gpio", "bumper_lines", parse_bumpers, print_bumpers),
    C_("gpio", "bumper_active_low", parse_bumper_low, print_bumper_low),
    C_("gpio", "estop_line", parse_estop, print_estop),
    C_("gpio", "estop_active_low", parse_estop_low, print_estop_low),
    C_("gpio", "led_lines", parse_leds, print_leds),

    S_("camera", "device", camera_device),
    N_("camera", "width_px", K_U32, camera_width_px, 16, 4096),
    N_("camera", "height_px", K_U32, camera_height_px, 16, 4096),
    B_("camera", "mjpeg_first", camera_mjpeg_first),
    S_("camera", "colour_table", camera_colour_table),
    S_("camera", "range_model", camera_range_model),
    N_("camera", "stall_timeout_s", K_US, camera_stall_us, 0.0, 60.0),
    S_("camera", "replay_log", camera_replay_log),
    B_("camera", "replay_loop", camera_replay_loop),

    N_("link", "domain", K_U32, link_domain, 0, 232),
    C_("link", "peers", parse_peers, print_peers),
    S_("link", "partition", link_partition),
    C_("link", "topic", parse_topic, print_topic),
    N_("link", "history_depth", K_U32, link_history_depth, 1, 10000),
    S_("link", "config", link_config),
    B_("link", "insecure", link_insecure),

    S_("storage", "dir", storage_dir),

    S_("fleet", "key_file", fleet_key_file),
    N_("fleet", "key_id", K_U8, fleet_key_id, 0, 255),
    NO_("fleet", "window_s", K_F64, fleet_window_s, 0.0, 86400.0),

    C_("filter", "type", parse_filter_type, print_filter_type),
    N_("filter", "particles", K_U16, node.filter.n_particles, 1, COSLAM_MAX_PARTICLES),
    N_("filter", "seed", K_U64, node.filter.seed, 0, 4294967295.0),
    NO_("filter", "ess_fraction", K_F64, node.filter.resample_ess_fraction, 0.0, 1.0),
    NO_("filter", "export_min_weight", K_F64, node.filter.export_min_weight, 0.0, 1.0),
    N_("filter", "closure_drift_ratio", K_F64, node.filter.closure_drift_ratio, 0.0, 1e9),
    N_("filter", "closure_gap", K_U16, node.filter.closure_gap, 0, 65535),
    N_("filter", "closure_ambiguity_ll", K_F64, node.filter.closure_ambiguity_ll, 0.0, 1e9),
    N_("filter", "closure_misses_per_support", K_F64, node.filter.closure_misses_per_support, 0.0, 1e9),
    N_("filter", "closure_chance_max", K_F64, node.filter.closure_chance_max, 0.0, 1e9),
    N_("filter", "closure_unsupported_every", K_U16, node.filter.closure_unsupported_every, 0, 65535),
    C_("filter", "assoc", parse_assoc, print_assoc),
    N_("filter", "jcbb_max_nodes", K_U32, node.filter.jcbb_max_nodes, 1, 100000000),
    B_("filter", "fej", node.filter.fej),
    N_("filter", "iekf_max_iters", K_U8, node.filter.iekf_max_iters, 0, 255),
    N_("filter", "nis_inflate", K_F64, node.filter.nis_inflate, 0.0, 1e6),
    N_("filter", "active_spread_madds", K_U32, node.filter.active_spread_madds, 0, 4294967295.0),
    N_("filter", "mh_frames", K_U32, node.filter.mh_frames, 0, 100000),
    N_("filter", "predict_period_s", K_US, node.filter_period_us, 0.001, 10.0),

    NO_("merge", "window_s", K_US, node.meeting.pair_window_us, 0.0, 4000.0),
    N_("merge", "interval_s", K_US, node.meeting.remerge_period_us, 0.0, 4000.0),
    NO_("merge", "max_range_m", K_F64, node.meeting.max_range_m, 0.0, 1000.0),
    N_("merge", "export_min_obs", K_U16, node.meeting.export_min_obs, 1, 65535),
    N_("merge", "max_sends", K_U8, node.meeting.max_sends, 0, 255),
    N_("merge", "resend_s", K_US, node.meeting.resend_period_us, 0.001, 4000.0),
    N_("merge", "gap_s", K_US, node.meeting.meeting_gap_us, 0.0, 4000.0),
    N_("merge", "link_latency_s", K_US, node.meeting.link_latency_us, 0.0, 10.0),
    NO_("merge", "gate_chi2", K_F64, node.meeting.merge.gate_chi2, 0.0, INF_),
    N_("merge", "min_obs", K_U16, node.meeting.merge.min_obs, 0, 65535),
    N_("merge", "range_check_chi2", K_F64, node.meeting.merge.range_check_chi2, 0.0, INF_),
    N_("merge", "sender_speed_mps", K_F64, node.meeting.merge.peer_speed_mps, 0.0, 10.0),
    N_("merge", "sender_turn_radps", K_F64, node.meeting.merge.peer_turn_radps, 0.0, 10.0),
    B_("merge", "check", node.meeting.merge.check),
    N_("merge", "step_units", K_U32, node.meeting.merge.step_units, 0, 4294967295.0),

    NO_("behaviour", "cruise_mps", K_F64, node.behaviour.cruise_mps, 0.0, 2.0),
    NO_("behaviour", "max_turn_radps", K_F64, node.behaviour.max_turn_radps, 0.0, 6.0),
    N_("behaviour", "explore_s", K_F64, node.behaviour.explore_s, -1.0, 1e7),
    N_("behaviour", "rendezvous_x_m", K_F64, node.behaviour.rendezvous_m.x, -1e4, 1e4),
    N_("behaviour", "rendezvous_y_m", K_F64, node.behaviour.rendezvous_m.y, -1e4, 1e4),
    N_("behaviour", "linger_s", K_F64, node.behaviour.linger_s, 0.0, 1e7),
};

#define N_KEYS (sizeof keys / sizeof keys[0])

/* ---- defaults ------------------------------------------------------------ */

static void set_str(char *dst, const char *src)
{
    put_text(dst, ROBOT_CONFIG_PATH_MAX + 1u, "%s", src);
}

void robot_config_default(robot_config_t *c)
{
    memset(c, 0, sizeof *c);
    c->can_fd = -1;
    c->camera_live_fd = -1;
    c->gpio_fd = -1;
    c->robot_id = 0U;
    c->fleet_size = 2U;
    c->step_period_us = 10000U;
    c->status_period_s = 10.0;
    c->snapshot_period_s = 30.0;
    c->retry_period_s = 5.0;
    set_str(c->laser_device, "/dev/ttyACM0");
    c->laser_baud = 115200U;
    set_str(c->can_interface, "can0");
    set_str(c->gpio_chip, "gpiochip0");
    c->gpio_required = 1U;
    c->camera_width_px = 320U;
    c->camera_height_px = 240U;
    c->camera_mjpeg_first = 0U;
    set_str(c->camera_colour_table, "/usr/share/coslam/vision/colour_lut.bin");
    set_str(c->camera_range_model, "/usr/share/coslam/vision/range_model.txt");
    c->camera_stall_us = 2000000U;
    c->camera_replay_loop = 1U;
    c->link_domain = 0U;
    set_str(c->link_topic, ROBOT_CONFIG_DEFAULT_TOPIC);
    c->link_history_depth = 32U;
    c->link_insecure = 0U;
    set_str(c->storage_dir, "/var/lib/coslam");
    set_str(c->fleet_key_file, "/etc/coslam/fleet.key");
    c->fleet_key_id = 1U;
    c->fleet_window_s = 30.0;
    c->node = robot_node_config_default(0U, 2U);
    c->node.urg.reply_timeout_us = 300000U;
    c->node.laser_optional = 1U;
    c->node.gpio_optional = 1U;
}

/* ---- loading ------------------------------------------------------------- */

/* libinih keeps at most 49 characters of a section name (its MAX_SECTION) */
#define SECTION_NAME_MAX 49u
/* section headers a file may have (12 sections are known; an unknown one
 * is refused at its header) */
#define SECTIONS_MAX 32

typedef struct {
    robot_config_t *cfg;
    const char *name;
    int line;                 /* current line (our reader counts) */
    int err_line;             /* first error's line, 0: none */
    char msg[ROBOT_CONFIG_MSG_MAX + 1u];
    int slam_line[32];        /* line each [slam] key was read from (0: default) */
    int key_line[96];         /* line each other key was read from (0: default) */
    const char *text;         /* load_string: the rest of the text */
    FILE *file;
    /* the section headers read so far (a repeated one is refused) */
    struct {
        char name[SECTION_NAME_MAX + 1u];
        int line;
    } sections[SECTIONS_MAX];
    int n_sections;
    int key_since_section;    /* a key line since the last header (libinih's prev_name) */
} load_t;

/* src into dst with every byte outside printable ASCII as \xNN and a
 * backslash as \\ (cut to cap, terminated; an escape is never cut in
 * half). The backslash is escaped too, so that the echo is unambiguous: a
 * key typed as the four characters \x1B used to be said exactly as a key
 * holding the ESC byte. */
static void escape_text(char *dst, size_t cap, const char *src)
{
    size_t n = 0;
    for (; *src != '\0' && n + 1U < cap; ++src) {
        const unsigned char ch = (unsigned char)*src;
        if (ch == (unsigned char)'\\') {
            if (n + 3U > cap) {
                break;
            }
            dst[n++] = '\\';
            dst[n++] = '\\';
            continue;
        }
        if (ch >= 0x20U && ch <= 0x7EU) {
            dst[n++] = (char)ch;
            continue;
        }
        if (n + 5U > cap) {
            break;
        }
        put_text(dst + n, cap - n, "\\x%02X", (unsigned)ch);
        n += 4U;
    }
    dst[n] = '\0';
}

static void fail(load_t *st, const char *sec, const char *key, const char *reason)
{
    if (st->err_line != 0) {
        return; /* the first error wins */
    }
    st->err_line = st->line > 0 ? st->line : 1;
    char raw[ROBOT_CONFIG_MSG_MAX + 1u];
    if (key != NULL) {
        put_text(raw, sizeof raw, "[%s] %s: %s", sec, key, reason);
    } else {
        put_text(raw, sizeof raw, "%s", reason);
    }
    /* every message quotes text of the file (a key, a section name, a
     * value): a control byte there (an escape sequence) must not reach the
     * operator's terminal raw. Escaped here, the one way out of the file's
     * text into a message. */
    escape_text(st->msg, sizeof st->msg, raw);
}

static coslam_status_t set_number(robot_config_t *c, const cfg_key_t *k, const char *v, char *msg, size_t cap)
{
    double d = 0.0;
    if (slam_params_ini_parse_number(v, &d) != COSLAM_OK) {
        put_text(msg, cap, "not a finite number: '%s'", v);
        return COSLAM_E_ARG;
    }
    const int below = k->min_open ? !(d > k->min) : !(d >= k->min);
    if (below || !(d <= k->max)) {
        put_text(msg, cap, "%s is outside its domain %s%g, %g%s", v, k->min_open ? "(" : "[", k->min, k->max,
                       isinf(k->max) ? ")" : "]");
        return COSLAM_E_ARG;
    }
    uint8_t *p = (uint8_t *)c + k->offset;
    if (k->type != K_F64 && k->type != K_US && d != floor(d)) {
        put_text(msg, cap, "expected an integer, got '%s'", v);
        return COSLAM_E_ARG;
    }
    switch (k->type) {
    case K_U8: {
        const uint8_t x = (uint8_t)d;
        memcpy(p, &x, sizeof x);
        break;
    }
    case K_U16: {
        const uint16_t x = (uint16_t)d;
        memcpy(p, &x, sizeof x);
        break;
    }
    case K_U32: {
        const uint32_t x = (uint32_t)d;
        memcpy(p, &x, sizeof x);
        break;
    }
    case K_U64: {
        const uint64_t x = (uint64_t)d;
        memcpy(p, &x, sizeof x);
        break;
    }
    case K_US: {
        const uint32_t x = (uint32_t)llround(d * 1e6);
        if (d > 0.0 && x == 0U) {
            /* it would read back as 0, which means "never" or "off" */
            put_text(msg, cap, "%s is below the microsecond these durations are kept in (0 means off)", v);
            return COSLAM_E_ARG;
        }
        memcpy(p, &x, sizeof x);
        break;
    }
    default:
        memcpy(p, &d, sizeof d);
        break;
    }
    return COSLAM_OK;
}

_Static_assert(sizeof(((load_t *)0)->key_line) / sizeof(int) >= N_KEYS, "key_line too small");

static int on_ini(void *user, const char *section, const char *name, const char *value)
{
    load_t *st = (load_t *)user;
    st->key_since_section = 1;
    if (st->err_line != 0) {
        return 1; /* keep only the first error */
    }
    char msg[ROBOT_CONFIG_MSG_MAX + 1u];
    msg[0] = '\0';
    /* Only printable ASCII (and tabs) in values: a device path, address or
     * number never needs more, and every message below quotes the value,
     * which must not echo raw bytes to a terminal or log (found by fuzzing,
     * docs/fuzzing.md). */
    for (size_t j = 0; value[j] != '\0'; ++j) {
        const unsigned char ch = (unsigned char)value[j];
        if ((ch < 0x20U && ch != (unsigned char)'\t') || ch > 0x7EU) {
            put_text(msg, sizeof msg, "byte 0x%02X at character %u of the value is not printable ASCII", (unsigned)ch,
                     (unsigned)(j + 1U));
            fail(st, section, name, msg);
            return 0;
        }
    }
    if (strcmp(section, "slam") == 0) {
        const slam_params_ini_key_t *sk = slam_params_ini_find(name);
        if (sk != NULL && st->slam_line[slam_params_ini_index(sk)] != 0) {
            put_text(msg, sizeof msg, "given twice (first on line %d; an indented line continues the key above)",
                     st->slam_line[slam_params_ini_index(sk)]);
            fail(st, "slam", name, msg);
            return 0;
        }
        const coslam_status_t s = slam_params_ini_set(&st->cfg->node.filter.slam, name, value, msg, sizeof msg);
        if (s != COSLAM_OK) {
            /* an unknown key's message names it already */
            fail(st, "slam", s == COSLAM_E_UNSUPPORTED ? NULL : name, msg);
            return 0;
        }
        st->slam_line[slam_params_ini_index(slam_params_ini_find(name))] = st->line;
        return 1;
    }
    int section_known = 0;
    for (size_t i = 0; i < N_KEYS; ++i) {
        const cfg_key_t *k = &keys[i];
        if (strcmp(k->section, section) != 0) {
            continue;
        }
        section_known = 1;
        if (strcmp(k->name, name) != 0) {
            continue;
        }
        /* A key read twice is refused: libinih also hands over an indented
         * line as a continuation of the key above (INI_ALLOW_MULTILINE), so
         * a stray indented line would otherwise replace that key's value
         * silently (found by fuzzing, docs/fuzzing.md). */
        if (st->key_line[i] != 0) {
            put_text(msg, sizeof msg, "given twice (first on line %d; an indented line continues the key above)",
                     st->key_line[i]);
            fail(st, section, name, msg);
            return 0;
        }
        coslam_status_t s = COSLAM_OK;
        uint8_t *p = (uint8_t *)st->cfg + k->offset;
        switch (k->type) {
        case K_CUSTOM:
            s = k->parse(st->cfg, value, msg, sizeof msg);
            break;
        case K_BOOL:
            s = parse_bool_text(value, p, msg, sizeof msg);
            break;
        case K_STR:
            if (strlen(value) > ROBOT_CONFIG_PATH_MAX) {
                put_text(msg, sizeof msg, "longer than %u characters", ROBOT_CONFIG_PATH_MAX);
                s = COSLAM_E_ARG;
            } else if (value[0] == ';' || value[0] == '#') {
                /* "key =; text" is a value to libinih (no blank before the
                 * ';'), but printed back it would read as a comment */
                put_text(msg, sizeof msg, "a value cannot begin with '%c' (a comment needs a blank before it)",
                         value[0]);
                s = COSLAM_E_ARG;
            } else if (!fits_line(name, strlen(value))) {
                put_text(msg, sizeof msg, "too long: '%s = <value>' must fit in one line of %d characters", name,
                         INI_MAX_LINE - 2);
                s = COSLAM_E_ARG;
            } else {
                set_str((char *)p, value);
            }
            break;
        default:
            s = set_number(st->cfg, k, value, msg, sizeof msg);
            break;
        }
        if (s != COSLAM_OK) {
            fail(st, section, name, msg);
            return 0;
        }
        st->key_line[i] = st->line;
        return 1;
    }
    if (section[0] == '\0') {
        put_text(msg, sizeof msg, "key '%s' outside any [section]", name);
        fail(st, section, NULL, msg);
    } else if (!section_known) {
        put_text(msg, sizeof msg, "unknown section [%s] (key '%s')", section, name);
        fail(st, section, NULL, msg);
    } else {
        put_text(msg, sizeof msg, "unknown key '%s' in [%s]", name, section);
        fail(st, section, NULL, msg);
    }
    return 0;
}

/* A line longer than libinih's buffer would reach it cut in two, the rest
 * parsed as a line of its own (a long value could end in "key = value"):
 * it is an error instead, and the whole line is skipped (found by fuzzing,
 * docs/fuzzing.md). */
static void line_too_long(load_t *st, char *str, int num)
{
    char msg[64];
    put_text(msg, sizeof msg, "line longer than %d characters", num - 2);
    fail(st, "", NULL, msg);
    str[0] = '\n';
    str[1] = '\0';
}

/* A section header on this line, as libinih will read it: a section that
 * began before is refused at its second header, with the first one's line.
 * libinih merges the two without a word (a repeated section is almost
 * always an edit mistake: the later one was meant to replace the first, or
 * was pasted in; docs/robot.md "Configuration"). */
static void note_section(load_t *st, const char *line)
{
    const char *p = line;
    if (st->line == 1 && (unsigned char)p[0] == 0xEFU && (unsigned char)p[1] == 0xBBU &&
        (unsigned char)p[2] == 0xBFU) {
        p += 3; /* libinih skips a UTF-8 byte order mark on line 1 */
    }
    while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n' || *p == '\v' || *p == '\f') {
        ++p;
    }
    if (*p != '[' || (p > line && st->key_since_section)) {
        return; /* not a header; an indented line after a key continues its value */
    }
    /* the name ends at ']'; a ';' after a blank starts a comment first */
    const char *q = p + 1;
    int blank = 0;
    while (*q != '\0' && *q != ']' && !(blank && *q == ';')) {
        blank = *q == ' ' || *q == '\t';
        ++q;
    }
    if (*q != ']') {
        return; /* a syntax error: libinih says it at this line */
    }
    st->key_since_section = 0;
    size_t len = (size_t)(q - (p + 1));
    if (len > SECTION_NAME_MAX) {
        len = SECTION_NAME_MAX;
    }
    char msg[ROBOT_CONFIG_MSG_MAX + 1u];
    for (int i = 0; i < st->n_sections; ++i) {
        if (strlen(st->sections[i].name) == len && memcmp(st->sections[i].name, p + 1, len) == 0) {
            put_text(msg, sizeof msg,
                     "section [%s] again (it began on line %d): a repeated section is refused; put its keys in "
                     "the first",
                     st->sections[i].name, st->sections[i].line);
            fail(st, "", NULL, msg);
            return;
        }
    }
    /* an unknown section is refused at its header, with or without keys:
     * an empty [bogus] (a misspelt section whose keys were moved, a
     * header pasted from another tool's file) was taken without a word */
    int known = len == strlen("slam") && memcmp(p + 1, "slam", len) == 0;
    char list[160] = "slam";
    for (size_t i = 0; i < N_KEYS; ++i) {
        known = known || (strlen(keys[i].section) == len && memcmp(keys[i].section, p + 1, len) == 0);
        if (i == 0 || strcmp(keys[i].section, keys[i - 1U].section) != 0) { /* the table is grouped */
            const size_t n = strlen(list);
            put_text(list + n, sizeof list - n, ", %s", keys[i].section);
        }
    }
    if (!known) {
        char name[SECTION_NAME_MAX + 1u];
        memcpy(name, p + 1, len);
        name[len] = '\0';
        put_text(msg, sizeof msg, "unknown section [%s] (the sections: %s)", name, list);
        fail(st, "", NULL, msg);
        return;
    }
    if (st->n_sections == SECTIONS_MAX) {
        put_text(msg, sizeof msg, "LIMIT: more than %d section headers (robot_config.c SECTIONS_MAX)", SECTIONS_MAX);
        fail(st, "", NULL, msg);
        return;
    }
    memcpy(st->sections[st->n_sections].name, p + 1, len);
    st->sections[st->n_sections].name[len] = '\0';
    st->sections[st->n_sections].line = st->line;
    st->n_sections++;
}

/* Readers that count lines, so the handler knows where it is. */
static char *read_file_line(char *str, int num, void *stream)
{
    load_t *st = (load_t *)stream;
    /* by hand, not fgets: a NUL byte in the line must be seen as one, not
     * end the string there (it was then reported as a line too long) */
    int n = 0;
    int ch = EOF;
    int nul = 0;
    while (n < num - 1 && (ch = fgetc(st->file)) != EOF) {
        if (ch == '\0') {
            nul = 1;
            ch = ' ';
        }
        str[n++] = (char)ch;
        if (ch == '\n') {
            break;
        }
    }
    str[n] = '\0';
    if (n == 0) {
        return NULL; /* end of the file (or a read error: ferror, checked by the caller) */
    }
    st->line++;
    if (str[n - 1] != '\n' && ch != EOF && n == num - 1) {
        while ((ch = fgetc(st->file)) != EOF && ch != '\n') {
        }
        line_too_long(st, str, num);
    } else if (nul) {
        fail(st, "", NULL, "a NUL byte in the line (a binary file?)");
    } else {
        note_section(st, str);
    }
    return str;
}

static char *read_text_line(char *str, int num, void *stream)
{
    load_t *st = (load_t *)stream;
    if (st->text == NULL || *st->text == '\0' || num < 2) {
        return NULL;
    }
    const char *nl = strchr(st->text, '\n');
    size_t len = nl != NULL ? (size_t)(nl - st->text) + 1U : strlen(st->text);
    if (len > (size_t)num - 1U || (nl == NULL && len > (size_t)num - 2U)) {
        st->text += len;
        st->line++;
        line_too_long(st, str, num);
        return str;
    }
    memcpy(str, st->text, len);
    str[len] = '\0';
    st->text += len;
    if (len > 0U && str[len - 1U] == '\n') {
        st->line++;
    } else if (*st->text == '\0') {
        st->line++;
    }
    note_section(st, str);
    return str;
}

/* Derived settings and the rules between keys. */
/* The line a key was read from (0: not in the file). */
static int key_line_of(const load_t *st, const char *section, const char *name)
{
    for (size_t i = 0; i < N_KEYS; ++i) {
        if (strcmp(keys[i].section, section) == 0 && strcmp(keys[i].name, name) == 0) {
            return st->key_line[i];
        }
    }
    return 0;
}

/* Two keys that contradict each other: the later of the two in the file
 * is the one named, with its line. */
static void fail_pair(load_t *st, const char *sec_a, const char *key_a, const char *sec_b, const char *key_b,
                      const char *msg)
{
    const int la = key_line_of(st, sec_a, key_a);
    const int lb = key_line_of(st, sec_b, key_b);
    st->line = la > lb ? la : lb;
    fail(st, la > lb ? sec_a : sec_b, la > lb ? key_a : key_b, msg);
}

static void finish(load_t *st)
{
    robot_config_t *c = st->cfg;
    if (st->err_line != 0) {
        return;
    }
    const slam_params_ini_key_t *bad = NULL;
    const slam_params_ini_key_t *other = NULL;
    char msg[ROBOT_CONFIG_MSG_MAX + 1u];
    if (slam_params_ini_cross_check(&c->node.filter.slam, &bad, &other, msg, sizeof msg) != COSLAM_OK) {
        /* the later of the two keys in the file is the one that contradicts */
        const int lb = bad != NULL ? st->slam_line[slam_params_ini_index(bad)] : 0;
        const int lo = other != NULL ? st->slam_line[slam_params_ini_index(other)] : 0;
        const slam_params_ini_key_t *named = lo > lb ? other : bad;
        st->line = lo > lb ? lo : lb;
        fail(st, "slam", named != NULL ? named->name : "?", msg);
        return;
    }
    if (c->robot_id >= c->fleet_size) {
        /* the later of the two keys is the one that contradicts */
        const int a = st->key_line[0];
        const int b = st->key_line[1];
        st->line = a > b ? a : b;
        put_text(msg, sizeof msg, "id %u must be below fleet_size %u", (unsigned)c->robot_id,
                       (unsigned)c->fleet_size);
        fail(st, "robot", a > b ? "id" : "fleet_size", msg);
        return;
    }
    /* a camera and the replay log both: the replay log (a test source)
     * would silently replace the camera (robot_open_sightings), and a
     * robot left with a bench line in its file would map a canned log */
    if (c->camera_device[0] != '\0' && c->camera_replay_log[0] != '\0') {
        put_text(msg, sizeof msg,
                 "device and replay_log are both set: the replay log (a test source) would replace the camera; "
                 "set one of them");
        fail_pair(st, "camera", "device", "camera", "replay_log", msg);
        return;
    }
    /* a GPIO line in two roles: the gpio_roles driver would refuse it at
     * start with no file and line (robot_node_init: E_ARG) */
    uint32_t line;
    gpio_role_t ra, rb;
    if (gpio_roles_line_conflict(&c->node.gpio, &line, &ra, &rb)) {
        static const char *const key_of[] = {"bumper_lines", "estop_line", "led_lines"}; /* gpio_role_t */
        put_text(msg, sizeof msg, "GPIO line %lu is used by %s and by %s", (unsigned long)line, key_of[ra],
                 key_of[rb]);
        fail_pair(st, "gpio", key_of[ra], "gpio", key_of[rb], msg);
        return;
    }
    /* the drive-side watchdog (cia402_omni_init would refuse these with no file and line) */
    const cia402_omni_config_t *dc = &c->node.drive;
    int wheel = 0;
    switch (cia402_omni_watchdog_check(dc, &wheel)) {
    case CIA402_OMNI_WATCHDOG_MASTER_IS_WHEEL:
        put_text(msg, sizeof msg, "master node id %u is also wheel %d's node id", (unsigned)dc->drive.master_node_id,
                 wheel);
        fail_pair(st, "can", "master_node_id", "can", "node_ids", msg);
        return;
    case CIA402_OMNI_WATCHDOG_TIMEOUT_SHORT:
        put_text(msg, sizeof msg,
                 "watchdog_timeout_ms %u must be at least twice master_heartbeat_period_ms %u (one lost "
                 "heartbeat must not stop the robot)",
                 (unsigned)dc->drive.master_timeout_ms, (unsigned)dc->master_heartbeat_period_ms);
        fail_pair(st, "can", "watchdog_timeout_ms", "can", "master_heartbeat_period_ms", msg);
        return;
    case CIA402_OMNI_WATCHDOG_NO_PERIOD: /* the key's domain starts at 1 */
    case CIA402_OMNI_WATCHDOG_OK: break;
    }
    /* the heartbeat goes out from the control step: a longer step starves
     * the drives' watchdog, which then stops the base for good */
    if (dc->drive.master_node_id != 0U &&
        (uint64_t)c->step_period_us > (uint64_t)dc->master_heartbeat_period_ms * 1000U) {
        put_text(msg, sizeof msg,
                 "step_period_s %g is longer than [can] master_heartbeat_period_ms %u: the heartbeat the "
                 "drives' watchdog needs is sent once per step",
                 (double)c->step_period_us * 1e-6, (unsigned)dc->master_heartbeat_period_ms);
        fail_pair(st, "robot", "step_period_s", "can", "master_heartbeat_period_ms", msg);
        return;
    }
    robot_node_config_t *n = &c->node;
    n->robot_id = c->robot_id;
    n->n_robots = c->fleet_size;
    n->filter.robot_id = c->robot_id;
    n->retry_period_us = (uint32_t)llround(c->retry_period_s * 1e6);
    n->laser_optional = 1U;
    n->gpio_optional = 1U;
    n->motion_without_gpio = (uint8_t)(c->gpio_required ? 0U : 1U);
    /* one settings source: the meeting's robot sightings take the camera
     * noise of [slam] */
    meeting_config_noise_from(&n->meeting, &n->filter.slam);
}

static coslam_status_t report(load_t *st, int rc, char *msg, size_t cap)
{
    if (rc == -1) {
        put_text(msg, cap, "%s: cannot open the configuration file", st->name);
        return COSLAM_E_ARG;
    }
    if (rc == -2) {
        put_text(msg, cap, "%s: out of memory while reading", st->name);
        return COSLAM_E_ARG;
    }
    if (rc > 0 && (st->err_line == 0 || rc < st->err_line)) {
        /* a syntax error before the first error the keys found is the one
         * to say ("[robot" without "]" made the next line's key "outside
         * any [section]") */
        st->err_line = rc;
        put_text(st->msg, sizeof st->msg, "syntax error (expected [section], key = value or a comment)");
    }
    finish(st);
    if (st->err_line == 0) {
        if (msg != NULL && cap > 0U) {
            msg[0] = '\0';
        }
        return COSLAM_OK;
    }
    if (st->err_line < 0) {
        put_text(msg, cap, "%s: %s", st->name, st->msg);
    } else {
        put_text(msg, cap, "%s:%d: %s", st->name, st->err_line, st->msg);
    }
    return COSLAM_E_ARG;
}

coslam_status_t robot_config_load(robot_config_t *cfg, const char *path, char *msg, size_t msg_cap)
{
    if (cfg == NULL || path == NULL || msg == NULL) {
        return COSLAM_E_ARG;
    }
    static load_t st; /* ~3 KB; one load at a time (robot_config.h) */
    COSLAM_ASSERT(slam_params_ini_count() <= sizeof st.slam_line / sizeof st.slam_line[0]);
    memset(&st, 0, sizeof st);
    st.cfg = cfg;
    st.name = path;
    /* O_NONBLOCK: a FIFO at the path would otherwise wait for a writer
     * before anything could be said (and before the signal handlers) */
    const int fd = open(path, O_RDONLY | O_NONBLOCK);
    if (fd < 0) {
        const int e = errno;
        put_text(msg, msg_cap, "%s: cannot open the configuration file: %s", path, strerror(e));
        return COSLAM_E_ARG;
    }
    /* a directory opens (and reads as an empty file): refused, as is any
     * other file that is not a regular one (a FIFO, a device) */
    struct stat sb;
    if (fstat(fd, &sb) != 0 || !S_ISREG(sb.st_mode)) {
        (void)close(fd);
        put_text(msg, msg_cap, "%s: not a regular file (a directory, a FIFO or a device?)", path);
        return COSLAM_E_ARG;
    }
    st.file = fdopen(fd, "r");
    if (st.file == NULL) {
        (void)close(fd);
        return report(&st, -1, msg, msg_cap);
    }
    const int rc = ini_parse_stream(read_file_line, &st, on_ini, &st);
    /* a read error ends fgets like the end of the file: the keys after it
     * would be silently missing */
    const int read_error = ferror(st.file);
    (void)fclose(st.file);
    if (read_error) {
        put_text(msg, msg_cap, "%s: read error after line %d", path, st.line);
        return COSLAM_E_ARG;
    }
    return report(&st, rc, msg, msg_cap);
}

coslam_status_t robot_config_load_string(robot_config_t *cfg, const char *text, const char *name, char *msg,
                                         size_t msg_cap)
{
    if (cfg == NULL || text == NULL || name == NULL || msg == NULL) {
        return COSLAM_E_ARG;
    }
    static load_t st;
    COSLAM_ASSERT(slam_params_ini_count() <= sizeof st.slam_line / sizeof st.slam_line[0]);
    memset(&st, 0, sizeof st);
    st.cfg = cfg;
    st.name = name;
    st.text = text;
    const int rc = ini_parse_stream(read_text_line, &st, on_ini, &st);
    return report(&st, rc, msg, msg_cap);
}

/* ---- printing ------------------------------------------------------------ */

/* Shortest decimal text (up to `digits` significant digits) that reads back
 * as exactly v: what a person wrote stays as written. */
static void print_double(FILE *out, double v, int digits)
{
    char buf[40];
    for (int prec = 6; prec <= digits; ++prec) {
        put_text(buf, sizeof buf, "%.*g", prec, v);
        double back = 0.0;
        if (slam_params_ini_parse_number(buf, &back) == COSLAM_OK && back == v) {
            break;
        }
    }
    fputs(buf, out);
}

static void print_value(const robot_config_t *c, const cfg_key_t *k, FILE *out)
{
    const uint8_t *p = (const uint8_t *)c + k->offset;
    switch (k->type) {
    case K_CUSTOM:
        k->print(c, out);
        break;
    case K_BOOL:
    case K_U8: {
        uint8_t x;
        memcpy(&x, p, sizeof x);
        fprintf(out, "%u", (unsigned)x);
        break;
    }
    case K_U16: {
        uint16_t x;
        memcpy(&x, p, sizeof x);
        fprintf(out, "%u", (unsigned)x);
        break;
    }
    case K_U32: {
        uint32_t x;
        memcpy(&x, p, sizeof x);
        fprintf(out, "%lu", (unsigned long)x);
        break;
    }
    case K_U64: {
        uint64_t x;
        memcpy(&x, p, sizeof x);
        fprintf(out, "%llu", (unsigned long long)x);
        break;
    }
    case K_US: {
        uint32_t x;
        memcpy(&x, p, sizeof x);
        fprintf(out, "%.6f", (double)x * 1e-6);
        break;
    }
    case K_STR:
        fprintf(out, "%s", (const char *)p);
        break;
    default: {
        double x;
        memcpy(&x, p, sizeof x);
        print_double(out, x, 17);
        break;
    }
    }
}

void robot_config_print(const robot_config_t *c, FILE *out)
{
    fprintf(out, "; coslam-robot configuration (effective values; firmware/port/linux/robot.ini documents them)\n");
    const char *sec = "";
    for (size_t i = 0; i < N_KEYS; ++i) {
        const cfg_key_t *k = &keys[i];
        if (strcmp(k->section, sec) != 0) {
            sec = k->section;
            fprintf(out, "\n[%s]\n", sec);
        }
        fprintf(out, "%s = ", k->name);
        print_value(c, k, out);
        fprintf(out, "\n");
    }
    fprintf(out, "\n[slam]\n");
    for (size_t i = 0; i < slam_params_ini_count(); ++i) {
        const slam_params_ini_key_t *k = slam_params_ini_key(i);
        const double v = slam_params_ini_get(&c->node.filter.slam, k);
        fprintf(out, "%s = ", k->name);
        if (k->type == SLAM_PARAMS_INI_FLOAT) {
            /* shortest text whose float conversion gives the float back */
            char buf[40];
            for (int prec = 6; prec <= 9; ++prec) {
                put_text(buf, sizeof buf, "%.*g", prec, v);
                double back = 0.0;
                if (slam_params_ini_parse_number(buf, &back) == COSLAM_OK && (float)back == (float)v) {
                    break;
                }
            }
            fprintf(out, "%s\n", buf);
        } else {
            print_double(out, v, 17);
            fprintf(out, "\n");
        }
    }
}
