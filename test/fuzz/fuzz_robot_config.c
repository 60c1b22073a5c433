/*
 * libFuzzer target for the robot's INI loader (firmware/port/linux/
 * robot_config.c on libinih) and the [slam] key table it shares with
 * coslam-replay (firmware/app/src/slam_params_ini.c).
 *
 * The input is the INI text (cut at its first NUL, as a file read by
 * libinih would be). Seeds: corpus/fuzz_robot_config/ (robot.ini of
 * firmware/port/linux and small hand-written files); dictionary ini.dict.
 *
 * Properties checked, beyond "no crash, no ASan/UBSan report":
 *  - the load returns COSLAM_OK or COSLAM_E_ARG; the message is
 *    NUL-terminated inside its buffer and, on error, starts with the file
 *    name ("fuzz.ini:");
 *  - accepted: every [slam] key is finite and inside its documented domain
 *    (slam_params_ini_key_t), the cross-key rules and slam_params_validate()
 *    hold, every period is finite and >= 0, robot_id < fleet_size, every
 *    text field is NUL-terminated;
 *  - accepted: robot_config_print() writes a file that loads back (every
 *    [slam] key exactly) and prints the same text again (round trip);
 *  - slam_params_ini_parse_number() never returns a non-finite number.
 */
#define _GNU_SOURCE /* open_memstream, fmemopen */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "app/slam_params_ini.h"
#include "coslam/slam_params.h"
#include "robot_config.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void require(int ok)
{
    if (!ok) {
        abort();
    }
}

static void text_ok(const char *s)
{
    require(memchr(s, '\0', ROBOT_CONFIG_PATH_MAX + 1u) != NULL);
}

static void check_slam(const slam_params_t *p)
{
    for (size_t i = 0; i < slam_params_ini_count(); ++i) {
        const slam_params_ini_key_t *k = slam_params_ini_key(i);
        const double v = slam_params_ini_get(p, k);
        require(isfinite(v));
        require(k->min_open ? v > k->min : v >= k->min);
        require(v <= k->max);
    }
    const slam_params_ini_key_t *a = NULL;
    const slam_params_ini_key_t *b = NULL;
    require(slam_params_ini_cross_check(p, &a, &b, NULL, 0U) == COSLAM_OK);
    require(slam_params_validate(p) == COSLAM_OK);
}

static char *print_config(const robot_config_t *c)
{
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    require(f != NULL);
    robot_config_print(c, f);
    require(fclose(f) == 0);
    return text;
}

static char g_text[1U << 16];
static robot_config_t g_cfg;
static robot_config_t g_back;

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size >= sizeof g_text) {
        return 0;
    }
    memcpy(g_text, data, size);
    g_text[size] = '\0';

    /* the number parser every settings file uses */
    double num = 0.0;
    if (slam_params_ini_parse_number(g_text, &num) == COSLAM_OK) {
        require(isfinite(num));
    }

    char msg[ROBOT_CONFIG_MSG_MAX + 1u];
    memset(msg, 'x', sizeof msg);
    robot_config_default(&g_cfg);
    const coslam_status_t st = robot_config_load_string(&g_cfg, g_text, "fuzz.ini", msg, sizeof msg);
    require(st == COSLAM_OK || st == COSLAM_E_ARG);
    require(memchr(msg, '\0', sizeof msg) != NULL);
    if (getenv("FUZZ_TRACE") != NULL) {
        fprintf(stderr, "load: %d %s\n", (int)st, st == COSLAM_OK ? "" : msg);
    }
    if (st != COSLAM_OK) {
        require(strncmp(msg, "fuzz.ini:", 9) == 0);
        return 0;
    }

    check_slam(&g_cfg.node.filter.slam);
    require(isfinite(g_cfg.status_period_s) && g_cfg.status_period_s >= 0.0);
    require(isfinite(g_cfg.snapshot_period_s) && g_cfg.snapshot_period_s >= 0.0);
    require(isfinite(g_cfg.retry_period_s) && g_cfg.retry_period_s >= 0.0);
    require(isfinite(g_cfg.fleet_window_s) && g_cfg.fleet_window_s >= 0.0);
    require(g_cfg.robot_id < g_cfg.fleet_size);
    text_ok(g_cfg.laser_device);
    text_ok(g_cfg.can_interface);
    text_ok(g_cfg.gpio_chip);
    text_ok(g_cfg.camera_device);
    text_ok(g_cfg.camera_replay_log);
    text_ok(g_cfg.link_peers);
    text_ok(g_cfg.link_partition);
    text_ok(g_cfg.link_topic);
    text_ok(g_cfg.link_config);
    text_ok(g_cfg.storage_dir);
    text_ok(g_cfg.fleet_key_file);

    /* round trip through robot_config_print: the printed file loads, every
     * [slam] key comes back exactly, and printing again gives the same text
     * (the struct itself is not compared byte-wise: its padding is not
     * defined) */
    char *printed = print_config(&g_cfg);
    robot_config_default(&g_back);
    const coslam_status_t st2 = robot_config_load_string(&g_back, printed, "printed.ini", msg, sizeof msg);
    if (st2 != COSLAM_OK) {
        fprintf(stderr, "printed config refused: %s\n--- printed:\n%s\n", msg, printed);
        abort();
    }
    for (size_t i = 0; i < slam_params_ini_count(); ++i) {
        const slam_params_ini_key_t *k = slam_params_ini_key(i);
        if (slam_params_ini_get(&g_cfg.node.filter.slam, k) != slam_params_ini_get(&g_back.node.filter.slam, k)) {
            fprintf(stderr, "[slam] %s changed in the round trip\n", k->name);
            abort();
        }
    }
    require(g_back.robot_id == g_cfg.robot_id && g_back.fleet_size == g_cfg.fleet_size &&
            g_back.step_period_us == g_cfg.step_period_us && g_back.status_period_s == g_cfg.status_period_s &&
            g_back.fleet_window_s == g_cfg.fleet_window_s && strcmp(g_back.link_peers, g_cfg.link_peers) == 0 &&
            strcmp(g_back.laser_device, g_cfg.laser_device) == 0);
    char *again = print_config(&g_back);
    if (strcmp(printed, again) != 0) {
        fprintf(stderr, "round trip differs:\n--- first\n%s\n--- second\n%s\n", printed, again);
        abort();
    }
    free(again);
    free(printed);
    return 0;
}
