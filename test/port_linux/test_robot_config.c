/*
 * coslam-robot configuration: the default robot.ini loads and holds the
 * documented defaults; every kind of bad file is refused with FILE:LINE and
 * the binary exits with status 2; the meeting's robot-sighting noise comes
 * from [slam] (one settings source); the [link] / [fleet] keys, and the
 * fleet key file policy (missing, too open, not a key: exit 2).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmocka.h>

#include "app/slam_params_ini.h"
#include "hal/hal_clock_linux.h"
#include "robot_config.h"
#include "robot_sightings.h"

static robot_config_t cfg;

static char *print_to_string(const robot_config_t *c)
{
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    assert_non_null(f);
    robot_config_print(c, f);
    fclose(f);
    return buf;
}

static void default_file_loads_and_is_the_default(void **state)
{
    (void)state;
    char msg[600];
    robot_config_default(&cfg);
    const coslam_status_t st = robot_config_load(&cfg, COSLAM_ROBOT_INI, msg, sizeof msg);
    if (strcmp(COSLAM_PROFILE_NAME, "default") != 0) {
        /* robot.ini names the default profile: a build of another profile
         * refuses it, by name (the rest holds for the default build only) */
        assert_int_not_equal(st, COSLAM_OK);
        assert_non_null(strstr(msg, "capacity profile"));
        skip();
    }
    if (st != COSLAM_OK) {
        fprintf(stderr, "%s: %s\n", COSLAM_ROBOT_INI, msg);
    }
    assert_int_equal(st, COSLAM_OK);
    /* the documented file writes out exactly the built-in defaults */
    static robot_config_t def;
    robot_config_default(&def);
    char msg2[600];
    assert_int_equal(robot_config_load_string(&def, "", "empty.ini", msg2, sizeof msg2), COSLAM_OK);
    char *a = print_to_string(&cfg);
    char *b = print_to_string(&def);
    if (strcmp(a, b) != 0) {
        fprintf(stderr, "robot.ini:\n%s\ndefaults:\n%s\n", a, b);
    }
    assert_string_equal(a, b);
    free(a);
    free(b);
    assert_int_equal(cfg.step_period_us, 10000);
    assert_int_equal(cfg.node.n_robots, 2);
    assert_true(cfg.node.laser_optional);
    assert_true(cfg.node.gpio_optional);
    assert_false(cfg.node.motion_without_gpio); /* gpio.required = true */
}

static void print_reads_back(void **state)
{
    (void)state;
    char msg[600];
    robot_config_default(&cfg);
    const char *text = "[robot]\nid = 3\nfleet_size = 5\n[filter]\ntype = ekf\n[slam]\nbearing_var_rad2 = 0.1111\n"
                       "exist_miss = 0.1\n[gpio]\nbumper_lines = 4, 5, 6\nestop_line = -1\nrequired = no\n";
    assert_int_equal(robot_config_load_string(&cfg, text, "t.ini", msg, sizeof msg), COSLAM_OK);
    char *a = print_to_string(&cfg);
    static robot_config_t back;
    robot_config_default(&back);
    assert_int_equal(robot_config_load_string(&back, a, "printed.ini", msg, sizeof msg), COSLAM_OK);
    char *b = print_to_string(&back);
    assert_string_equal(a, b);
    assert_int_equal(back.robot_id, 3);
    assert_int_equal(back.node.filter.robot_id, 3);
    assert_int_equal(back.node.filter.kind, SLAM_FILTER_EKF);
    assert_int_equal(back.node.gpio.n_bumpers, 3);
    assert_false(back.node.gpio.has_estop);
    assert_true(back.node.motion_without_gpio);
    assert_true(back.node.filter.slam.exist_miss == 0.1f);
    free(a);
    free(b);
}

static void link_keys_defaults_and_round_trip(void **state)
{
    (void)state;
    char msg[600];
    robot_config_default(&cfg);
    assert_int_equal(cfg.link_domain, 0);
    assert_string_equal(cfg.link_peers, "");
    assert_string_equal(cfg.link_partition, "");
    assert_string_equal(cfg.link_topic, "rt/coslam/map");
    assert_int_equal(cfg.link_history_depth, 32);
    assert_string_equal(cfg.link_config, "");
    assert_false(cfg.link_insecure);
    assert_string_equal(cfg.fleet_key_file, "/etc/coslam/fleet.key");
    assert_int_equal(cfg.fleet_key_id, 1);
    assert_true(cfg.fleet_window_s == 30.0);
    const char *text = "[link]\ndomain = 232\npeers = 192.168.1.12 ,robot2.local,[fe80::1]\npartition = lab-b\n"
                       "topic = rt/lab_b/coslam_map\nhistory_depth = 64\nconfig = file:///etc/coslam/cyclonedds.xml\n"
                       "insecure = yes\n[fleet]\nkey_file =\nkey_id = 255\nwindow_s = 2.5\n";
    assert_int_equal(robot_config_load_string(&cfg, text, "l.ini", msg, sizeof msg), COSLAM_OK);
    assert_int_equal(cfg.link_domain, 232);
    assert_string_equal(cfg.link_peers, "192.168.1.12, robot2.local, [fe80::1]"); /* normalised */
    assert_string_equal(cfg.link_partition, "lab-b");
    assert_string_equal(cfg.link_topic, "rt/lab_b/coslam_map");
    assert_int_equal(cfg.link_history_depth, 64);
    assert_string_equal(cfg.link_config, "file:///etc/coslam/cyclonedds.xml");
    assert_true(cfg.link_insecure);
    assert_string_equal(cfg.fleet_key_file, "");
    assert_int_equal(cfg.fleet_key_id, 255);
    assert_true(cfg.fleet_window_s == 2.5);
    char *a = print_to_string(&cfg);
    static robot_config_t back;
    robot_config_default(&back);
    assert_int_equal(robot_config_load_string(&back, a, "printed.ini", msg, sizeof msg), COSLAM_OK);
    char *b = print_to_string(&back);
    assert_string_equal(a, b);
    assert_string_equal(back.link_peers, cfg.link_peers);
    assert_string_equal(back.fleet_key_file, "");
    free(a);
    free(b);
}

static void meeting_noise_comes_from_slam(void **state)
{
    (void)state;
    char msg[600];
    robot_config_default(&cfg);
    const char *text = "[slam]\nrange_var_m2 = 0.0025\nbearing_var_rad2 = 0.0009\nrange_var_per_m2 = 0.01\n";
    assert_int_equal(robot_config_load_string(&cfg, text, "n.ini", msg, sizeof msg), COSLAM_OK);
    assert_true(cfg.node.meeting.robot_range_var_m2 == 0.0025);
    assert_true(cfg.node.meeting.robot_bearing_var_rad2 == 0.0009);
    assert_true(cfg.node.meeting.robot_range_var_per_m2 == 0.01);
}

/* The message of a refused text, which must contain `want`. */
static void refused(const char *text, const char *want)
{
    char msg[600];
    robot_config_default(&cfg);
    const coslam_status_t st = robot_config_load_string(&cfg, text, "bad.ini", msg, sizeof msg);
    if (st == COSLAM_OK || strstr(msg, want) == NULL) {
        fprintf(stderr, "text:\n%s\nmessage: %s\nwanted: %s\n", text, msg, want);
    }
    assert_int_equal(st, COSLAM_E_ARG);
    assert_non_null(strstr(msg, want));
    /* text of the file is quoted escaped: nothing but printable ASCII
     * reaches the operator's terminal */
    for (const char *p = msg; *p != '\0'; ++p) {
        assert_true(*p >= 0x20 && *p <= 0x7E);
    }
}

/* The Fast-SLAM revisit keys and EKF-SLAM's innovation monitor: the core's
 * defaults, and they reach the filter. */
static void closure_keys_reach_the_filter(void **state)
{
    (void)state;
    char msg[600];
    robot_config_default(&cfg);
    const fastslam_config_t fc = fastslam_config_default();
    assert_true(cfg.node.filter.closure_drift_ratio == fc.closure_drift_ratio);
    assert_int_equal(cfg.node.filter.closure_gap, fc.closure_gap);
    assert_true(cfg.node.filter.closure_ambiguity_ll == fc.closure_ambiguity_ll);
    assert_true(cfg.node.filter.closure_misses_per_support == fc.closure_misses_per_support);
    assert_int_equal(cfg.node.filter.closure_unsupported_every, fc.closure_unsupported_every);
    assert_true(cfg.node.filter.closure_chance_max == fc.closure_chance_max);
    assert_true(cfg.node.filter.nis_inflate == ekfslam_config_default().nis_inflate);
    assert_true(cfg.node.filter.active_spread_madds == ekfslam_config_default().active_spread_madds);
    assert_true(cfg.node.filter.mh_frames == ekfslam_config_default().mh_frames);
    const char *text = "[filter]\nclosure_drift_ratio = 0\nclosure_gap = 7\nclosure_ambiguity_ll = 1.5\nnis_inflate = 0\n"
                       "active_spread_madds = 2000000\nmh_frames = 9\nclosure_misses_per_support = 3.5\nclosure_unsupported_every = 5\nclosure_chance_max = 0.5\n";
    assert_int_equal(robot_config_load_string(&cfg, text, "c.ini", msg, sizeof msg), COSLAM_OK);
    assert_true(cfg.node.filter.closure_drift_ratio == 0.0);
    assert_int_equal(cfg.node.filter.closure_gap, 7);
    assert_true(cfg.node.filter.closure_ambiguity_ll == 1.5);
    /* and the filter built from it holds them */
    static slam_filter_t f;
    cfg.node.filter.kind = SLAM_FILTER_FASTSLAM2;
    assert_int_equal(slam_filter_init(&f, &cfg.node.filter, (pose2_t){0.0, 0.0, 0.0}), COSLAM_OK);
    assert_true(f.u.fs.cfg.closure_drift_ratio == 0.0);
    assert_int_equal(f.u.fs.cfg.closure_gap, 7);
    assert_true(f.u.fs.cfg.closure_ambiguity_ll == 1.5);
    assert_true(f.u.fs.cfg.closure_misses_per_support == 3.5);
    assert_int_equal(f.u.fs.cfg.closure_unsupported_every, 5);
    assert_true(f.u.fs.cfg.closure_chance_max == 0.5);
    cfg.node.filter.kind = SLAM_FILTER_EKF;
    assert_int_equal(slam_filter_init(&f, &cfg.node.filter, (pose2_t){0.0, 0.0, 0.0}), COSLAM_OK);
    assert_true(f.u.ekf.cfg.nis_inflate == 0.0);
    assert_true(f.u.ekf.cfg.active_spread_madds == 2000000U);
    assert_true(f.u.ekf.cfg.mh_frames == 9U);
    assert_true(f.u.ekf.alt == &f.u.ekf2.alt); /* the second hypothesis has its storage */
}

/* The drive-side watchdog's keys: the drivers' defaults, read, printed
 * back, checked against each other and the wheels' ids, and accepted by
 * the drive driver as loaded. */
static void watchdog_keys_reach_the_drive(void **state)
{
    (void)state;
    char msg[600];
    robot_config_default(&cfg);
    const cia402_omni_config_t oc = cia402_omni_config_default();
    assert_int_equal(cfg.node.drive.drive.master_node_id, oc.drive.master_node_id);
    assert_int_equal(cfg.node.drive.drive.master_node_id, 127);
    assert_int_equal(cfg.node.drive.drive.master_timeout_ms, 200);
    assert_int_equal(cfg.node.drive.master_heartbeat_period_ms, 50);
    assert_int_equal(cfg.node.drive.drive.master_loss_action, CIA402_ABORT_QUICK_STOP);
    const char *text = "[can]\nnode_ids = 4, 5, 6\nmaster_node_id = 1\nmaster_heartbeat_period_ms = 20\n"
                       "watchdog_timeout_ms = 100\nwatchdog_action = disable_voltage\n";
    assert_int_equal(robot_config_load_string(&cfg, text, "w.ini", msg, sizeof msg), COSLAM_OK);
    assert_int_equal(cfg.node.drive.drive.master_node_id, 1);
    assert_int_equal(cfg.node.drive.master_heartbeat_period_ms, 20);
    assert_int_equal(cfg.node.drive.drive.master_timeout_ms, 100);
    assert_int_equal(cfg.node.drive.drive.master_loss_action, CIA402_ABORT_DISABLE_VOLTAGE);
    char *a = print_to_string(&cfg);
    assert_non_null(strstr(a, "watchdog_action = disable_voltage"));
    static robot_config_t back;
    robot_config_default(&back);
    assert_int_equal(robot_config_load_string(&back, a, "printed.ini", msg, sizeof msg), COSLAM_OK);
    char *b = print_to_string(&back);
    assert_string_equal(a, b);
    free(a);
    free(b);
    /* the driver takes what the file gave */
    static cia402_omni_t o;
    hal_can_t can;
    memset(&can, 0, sizeof can);
    assert_int_equal(cia402_omni_init(&o, &cfg.node.drive, &can), COSLAM_OK);
    assert_int_equal(o.drive[2].cfg.master_timeout_ms, 100);
    /* off: the other keys are not checked against each other */
    assert_int_equal(robot_config_load_string(&cfg, "[can]\nmaster_node_id = 0\nwatchdog_timeout_ms = 1\n", "o.ini", msg,
                                              sizeof msg),
                     COSLAM_OK);
}

static void bad_files_name_file_and_line(void **state)
{
    (void)state;
    refused("[filter]\nclosure_drift_ratio = -1\n", "bad.ini:2: [filter] closure_drift_ratio: -1 is outside its domain");
    refused("[filter]\nclosure_gap = 70000\n", "bad.ini:2: [filter] closure_gap: 70000 is outside its domain");
    refused("[filter]\nclosure_misses_per_support = -1\n",
            "bad.ini:2: [filter] closure_misses_per_support: -1 is outside its domain");
    refused("[filter]\nclosure_chance_max = -0.5\n", "bad.ini:2: [filter] closure_chance_max: -0.5 is outside its domain");
    refused("[filter]\nclosure_unsupported_every = 70000\n",
            "bad.ini:2: [filter] closure_unsupported_every: 70000 is outside its domain");
    refused("[filter]\nnis_inflate = -1\n", "bad.ini:2: [filter] nis_inflate: -1 is outside its domain");
    refused("[filter]\nactive_spread_madds = -1\n",
            "bad.ini:2: [filter] active_spread_madds: -1 is outside its domain");
    refused("[robot]\nid = 0\n\n[nosuch]\nkey = 1\n", "bad.ini:4: unknown section [nosuch] (the sections: slam, robot");
    /* an unknown section without keys: refused at its header too (it was
     * taken without a word; only a key in it was refused) */
    refused("[robot]\nid = 0\n[bogus]\n", "bad.ini:3: unknown section [bogus]");
    refused("[laser]\ndevice = /dev/x\nspeed = 3\n", "bad.ini:3: unknown key 'speed' in [laser]");
    refused("[slam]\n\nrange_var_m3 = 1\n", "bad.ini:3: unknown key 'range_var_m3' in [slam]");
    refused("[slam]\ngate_chi2 = abc\n", "bad.ini:2: [slam] gate_chi2: not a finite number: 'abc'");
    refused("[robot]\nstep_period_s = 10ms\n", "bad.ini:2: [robot] step_period_s: not a finite number");
    refused("[robot]\nstep_period_s = 5\n", "bad.ini:2: [robot] step_period_s: 5 is outside its domain [0.001, 1]");
    refused("[slam]\nbearing_var_rad2 = 0\n", "bad.ini:2: [slam] bearing_var_rad2: 0 is outside its domain (0, 0.25]");
    /* sent with the sightings of partners, who refuse more than 0.25 rad^2 */
    refused("[slam]\nbearing_var_rad2 = 0.3\n", "bad.ini:2: [slam] bearing_var_rad2: 0.3 is outside its domain (0, 0.25]");
    refused("[slam]\nvisibility_margin = 1.5\n", "bad.ini:2: [slam] visibility_margin:");
    refused("[filter]\nparticles = 2.5\n", "bad.ini:2: [filter] particles: expected an integer");
    refused("[filter]\nparticles = 100000\n", "bad.ini:2: [filter] particles: 100000 is outside");
    refused("[filter]\ntype = kalman\n", "bad.ini:2: [filter] type: unknown filter 'kalman'");
    refused("[gpio]\nrequired = maybe\n", "bad.ini:2: [gpio] required: expected a boolean");
    refused("[gpio]\nbumper_lines = 1, x\n", "bad.ini:2: [gpio] bumper_lines: expected an integer");
    refused("[can]\nnode_ids = 1, 2\n", "bad.ini:2: [can] node_ids: expected 3 CANopen node ids");
    refused("[can]\nmaster_node_id = 128\n", "bad.ini:2: [can] master_node_id: 128 is outside its domain [0, 127]");
    refused("[can]\nwatchdog_action = stop\n",
            "bad.ini:2: [can] watchdog_action: expected quick_stop, disable_voltage or fault");
    refused("[can]\nmaster_node_id = 2\n", "bad.ini:2: [can] master_node_id: master node id 2 is also wheel 1's node id");
    refused("[can]\nmaster_node_id = 9\n\nnode_ids = 7, 8, 9\n",
            "bad.ini:4: [can] node_ids: master node id 9 is also wheel 2's node id");
    refused("[robot]\nstep_period_s = 0.25\n",
            "bad.ini:2: [robot] step_period_s: step_period_s 0.25 is longer than [can] master_heartbeat_period_ms 50");
    refused("[robot]\nstep_period_s = 0.02\n[can]\nmaster_heartbeat_period_ms = 10\nwatchdog_timeout_ms = 100\n",
            "bad.ini:4: [can] master_heartbeat_period_ms: step_period_s 0.02 is longer than");
    refused("[can]\nwatchdog_timeout_ms = 60\n",
            "bad.ini:2: [can] watchdog_timeout_ms: watchdog_timeout_ms 60 must be at least twice "
            "master_heartbeat_period_ms 50");
    /* a profile this build is not */
    refused(strcmp(COSLAM_PROFILE_NAME, "large") != 0 ? "[robot]\nprofile = large\n" : "[robot]\nprofile = host\n",
            "bad.ini:2: [robot] profile: this binary is built for");
    refused("this is not ini\n", "bad.ini:1: syntax error");
    refused("key = 1\n", "bad.ini:1: key 'key' outside any [section]");
    /* two keys that contradict each other: the line of the later one */
    refused("[slam]\nsensor_min_range_m = 2\n\n# comment\nsensor_max_range_m = 1\n",
            "bad.ini:5: [slam] sensor_max_range_m: sensor_max_range_m must be greater than sensor_min_range_m");
    refused("[slam]\ngate_chi2 = 30\n", "bad.ini:2: [slam] gate_chi2: new_landmark_chi2 must be at least gate_chi2");
    refused("[robot]\nfleet_size = 3\nid = 3\n", "bad.ini:3: [robot] id: id 3 must be below fleet_size 3");
    /* [link] and [fleet] */
    refused("[link]\ndomain = 233\n", "bad.ini:2: [link] domain: 233 is outside its domain [0, 232]");
    refused("[link]\ndomain = -1\n", "bad.ini:2: [link] domain: -1 is outside its domain");
    refused("[link]\n\npeers = 10.0.0.2, <robot3/>\n",
            "bad.ini:3: [link] peers: peer address '<robot3/>' has a character other than");
    refused("[link]\npeers = 10.0.0.2,,10.0.0.3\n", "bad.ini:2: [link] peers: empty peer address");
    refused("[link]\npeers = 10.0.0.2,\n", "bad.ini:2: [link] peers: empty peer address after the last comma");
    refused("[link]\npeers = a,b,c,d,e,f,g,h,i,j,k,l,m,n,o,p,q\n", "bad.ini:2: [link] peers: at most 16 peers");
    refused("[link]\ntopic = rt/coslam map\n", "bad.ini:2: [link] topic: topic 'rt/coslam map' has a character");
    refused("[link]\ntopic =\n", "bad.ini:2: [link] topic: empty topic");
    refused("[link]\nhistory_depth = 0\n", "bad.ini:2: [link] history_depth: 0 is outside its domain [1, 10000]");
    refused("[link]\ninsecure = perhaps\n", "bad.ini:2: [link] insecure: expected a boolean");
    refused("[fleet]\nkey_id = 256\n", "bad.ini:2: [fleet] key_id: 256 is outside its domain [0, 255]");
    refused("[fleet]\nwindow_s = 0\n", "bad.ini:2: [fleet] window_s: 0 is outside its domain (0, 86400]");
    refused("[fleet]\nkey = 00112233\n", "bad.ini:2: unknown key 'key' in [fleet]");
    /* one GPIO line in two roles: the later key's line */
    refused("[gpio]\nbumper_lines = 1, 2\n\nestop_line = 2\n",
            "bad.ini:4: [gpio] estop_line: GPIO line 2 is used by bumper_lines and by estop_line");
    refused("[gpio]\nled_lines = 5\nbumper_lines = 5\n",
            "bad.ini:3: [gpio] bumper_lines: GPIO line 5 is used by bumper_lines and by led_lines");
    /* a positive duration that would read back as 0 ("never", "off") */
    refused("[laser]\nlost_timeout_s = 0.0000001\n",
            "bad.ini:2: [laser] lost_timeout_s: 0.0000001 is below the microsecond these durations are kept in");
    refused("[merge]\nwindow_s = 1e-7\n", "bad.ini:2: [merge] window_s: 1e-7 is below the microsecond");
    /* 0 sent the map again in every frame until the meeting's budget was
     * spent (coslam-sim and coslam-replay refuse it too) */
    refused("[merge]\nresend_s = 0\n", "bad.ini:2: [merge] resend_s: 0 is outside its domain");
    /* a section header without its ']': said at its own line, not as the
     * next line's key "outside any [section]" */
    refused("[robot\nid = 1\n", "bad.ini:1: syntax error");
    /* the camera and the test source both: refused at the later key */
    refused("[camera]\ndevice = /dev/video0\nreplay_log = lm.log\n",
            "bad.ini:3: [camera] replay_log: device and replay_log are both set");
    /* the first error wins */
    refused("[robot]\nid = x\n[laser]\nfoo = 1\n", "bad.ini:2:");
    /* control bytes in a key or a section name are quoted as \xNN (an
     * escape sequence in the file used to reach the terminal raw) */
    refused("[robot]\nid = 0\n[la\x1b[31mser]\nx = 1\n", "bad.ini:3: unknown section [la\\x1B[31mser]");
    refused("[laser]\n\x1b]0;owned\x07 = 1\n", "bad.ini:2: unknown key '\\x1B]0;owned\\x07' in [laser]");
    refused("[slam]\nrange\x9b" "2J = 1\n", "bad.ini:2: unknown key 'range\\x9B2J' in [slam]");
    refused("\x1b[2Jid = 1\n", "bad.ini:1: key '\\x1B[2Jid' outside any [section]");
    /* a backslash typed in the file is said as \\: the echo of the four
     * characters \x1B is not that of the ESC byte (it was the same) */
    refused("[laser]\n\\x1B]0;owned = 1\n", "bad.ini:2: unknown key '\\\\x1B]0;owned' in [laser]");
    refused("[robot]\nid = 1\\x41\n", "bad.ini:2: [robot] id: not a finite number: '1\\\\x41'");
    /* a repeated section: refused at its second header, with the first's
     * line (libinih merged the two without a word) */
    refused("[robot]\nid = 1\n\n[laser]\ndevice =\n[robot]\nfleet_size = 3\n",
            "bad.ini:6: section [robot] again (it began on line 1): a repeated section is refused");
    refused("[gpio]\n[gpio] ; again\n", "bad.ini:2: section [gpio] again (it began on line 1)");
    refused("[slam]\ngate_chi2 = 9\n[slam]\n", "bad.ini:3: section [slam] again (it began on line 1)");
    refused("[x\x1b]\n[x\x1b]\n", "bad.ini:1: unknown section [x\\x1B]"); /* only known sections repeat */
    char msg[600];
    robot_config_default(&cfg);
    assert_int_equal(robot_config_load(&cfg, "/nonexistent/robot.ini", msg, sizeof msg), COSLAM_E_ARG);
    assert_non_null(strstr(msg, "/nonexistent/robot.ini: cannot open the configuration file: No such file"));
    /* a directory opens and reads as an empty file: refused, not defaults */
    assert_int_equal(robot_config_load(&cfg, "/tmp", msg, sizeof msg), COSLAM_E_ARG);
    assert_non_null(strstr(msg, "/tmp: not a regular file"));
    /* a NUL byte: said as one (it was "line longer than 198 characters") */
    char nulpath[64];
    snprintf(nulpath, sizeof nulpath, "/tmp/coslam-cfg-nul-%d.ini", (int)getpid());
    FILE *nf = fopen(nulpath, "w");
    assert_non_null(nf);
    fwrite("[robot]\nid = 1\0\n", 1, 17, nf);
    fclose(nf);
    assert_int_equal(robot_config_load(&cfg, nulpath, msg, sizeof msg), COSLAM_E_ARG);
    assert_non_null(strstr(msg, ":2: a NUL byte in the line"));
    assert_int_equal(unlink(nulpath), 0);
    /* a FIFO: refused at once (it used to wait for a writer for ever) */
    char fifo[64];
    snprintf(fifo, sizeof fifo, "/tmp/coslam-cfg-fifo-%d", (int)getpid());
    (void)unlink(fifo);
    assert_int_equal(mkfifo(fifo, 0600), 0);
    assert_int_equal(robot_config_load(&cfg, fifo, msg, sizeof msg), COSLAM_E_ARG);
    assert_non_null(strstr(msg, "not a regular file"));
    assert_int_equal(unlink(fifo), 0);
    /* a read error ends the parse like the end of the file: refused and
     * named, never taken for a shorter file with defaults after it.
     * /proc/self/mem is a regular file whose read at offset 0 fails (EIO:
     * nothing is mapped at address 0) */
    int fd = open("/proc/self/mem", O_RDONLY);
    char byte;
    const int read_fails = fd >= 0 && read(fd, &byte, 1) < 0 && errno == EIO;
    if (fd >= 0) {
        close(fd);
    }
    if (!read_fails) {
        print_message("skipped the read-error case: /proc/self/mem does not fail its read with EIO here\n");
        return;
    }
    robot_config_default(&cfg);
    static robot_config_t defaults;
    memcpy(&defaults, &cfg, sizeof cfg);
    assert_int_equal(robot_config_load(&cfg, "/proc/self/mem", msg, sizeof msg), COSLAM_E_ARG);
    assert_non_null(strstr(msg, "/proc/self/mem: read error after line 0"));
    assert_memory_equal(&cfg, &defaults, sizeof cfg); /* nothing read: the defaults as they were */
}

/* Run the binary on a file; returns the exit status, stderr into err. */
static int run_robot(const char *text, const char *extra, char *err, size_t cap)
{
    char dir[] = "/tmp/coslam-robot-cfg-XXXXXX";
    assert_non_null(mkdtemp(dir));
    char path[256];
    snprintf(path, sizeof path, "%s/robot.ini", dir);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
    char cmd[1024];
    snprintf(cmd, sizeof cmd, "%s -c %s %s 2>&1 >/dev/null", COSLAM_ROBOT_BIN, path, extra);
    FILE *p = popen(cmd, "r");
    assert_non_null(p);
    size_t n = fread(err, 1, cap - 1, p);
    err[n] = '\0';
    const int st = pclose(p);
    unlink(path);
    rmdir(dir);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* The start-up says whether the drives are guarded by the watchdog. */
static void binary_says_the_drive_watchdog(void **state)
{
    (void)state;
    char err[8192];
    const char *base = "[laser]\ndevice =\n[gpio]\nchip =\n[fleet]\nkey_file =\n[storage]\ndir = /nonexistent-coslam/wd-store\n"
                       "[can]\ninterface = nosuchcan0\n";
    assert_int_equal(run_robot(base, "--dry-run", err, sizeof err), 0);
    assert_non_null(strstr(err, "can: drive watchdog: heartbeat as node 127 every 50 ms; a drive that misses it for "
                                "200 ms stops its wheel (quick_stop)"));
    char text[512];
    snprintf(text, sizeof text, "%smaster_node_id = 0\n", base);
    assert_int_equal(run_robot(text, "--dry-run", err, sizeof err), 0);
    assert_non_null(strstr(err, "can: warning: no drive watchdog ([can] master_node_id = 0): if this process dies or "
                                "hangs, the wheels keep their last command"));
    /* no CAN interface configured: nothing to say about drives */
    assert_int_equal(run_robot("[laser]\ndevice =\n[gpio]\nchip =\n[fleet]\nkey_file =\n[storage]\ndir = "
                               "/nonexistent-coslam/wd-store\n[can]\ninterface =\n",
                               "--dry-run", err, sizeof err),
                     0);
    assert_null(strstr(err, "drive watchdog"));
}

static void binary_exits_2_with_file_and_line(void **state)
{
    (void)state;
    char err[4096];
    assert_int_equal(run_robot("[robot]\nid = 0\n[laser]\nbaud = fast\n", "--dry-run", err, sizeof err), 2);
    assert_non_null(strstr(err, "robot.ini:4: [laser] baud: not a finite number"));
    assert_int_equal(run_robot("[slam]\nsensor_fov_rad = 7\n", "--dry-run", err, sizeof err), 2);
    assert_non_null(strstr(err, "robot.ini:2: [slam] sensor_fov_rad"));
    assert_int_equal(run_robot("[camera]\nlens = wide\n", "", err, sizeof err), 2);
    assert_non_null(strstr(err, "robot.ini:2: unknown key 'lens' in [camera]"));
    assert_int_equal(run_robot("", "--no-such-option", err, sizeof err), 2);
    /* a missing file */
    char cmd[512];
    snprintf(cmd, sizeof cmd, "%s -c /nonexistent/robot.ini >/dev/null 2>&1", COSLAM_ROBOT_BIN);
    const int st = system(cmd);
    assert_true(WIFEXITED(st));
    assert_int_equal(WEXITSTATUS(st), 2);
    /* --print-config of a good file: exit 0 */
    assert_int_equal(run_robot("[robot]\nid = 1\n", "--print-config", err, sizeof err), 0);
    /* a repeated section, read from a file */
    assert_int_equal(run_robot("[robot]\nid = 1\n[laser]\n[robot]\nfleet_size = 3\n", "--dry-run", err, sizeof err), 2);
    assert_non_null(strstr(err, "robot.ini:4: section [robot] again (it began on line 1)"));
    /* a bad DDS domain */
    assert_int_equal(run_robot("[link]\ndomain = 300\n", "--dry-run", err, sizeof err), 2);
    assert_non_null(strstr(err, "robot.ini:2: [link] domain: 300 is outside its domain [0, 232]"));
}

/* The fleet key file: configured but missing, too open or not a key -> the
 * robot does not start (exit 2, the file and the reason named, the key
 * never printed); 0600 and 0640 are good. */
static void binary_refuses_a_bad_fleet_key(void **state)
{
    (void)state;
#if !(COSLAM_HAVE_DDS && COSLAM_HAVE_LINK_AUTH)
    skip(); /* no link in this build: the key is never read */
#endif
    char dir[] = "/tmp/coslam-robot-key-XXXXXX";
    assert_non_null(mkdtemp(dir));
    char key[300];
    snprintf(key, sizeof key, "%s/fleet.key", dir);
    char xml[300];
    snprintf(xml, sizeof xml, "%s/cyclone.xml", dir);
    FILE *x = fopen(xml, "w");
    assert_non_null(x);
    /* loopback only, no multicast: the good-key dry run opens DDS */
    fputs("<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface address=\"127.0.0.1\"/>"
          "</Interfaces><AllowMulticast>false</AllowMulticast></General>"
          "<Tracing><Verbosity>severe</Verbosity><OutputFile>stderr</OutputFile></Tracing></Domain></CycloneDDS>\n",
          x);
    fclose(x);
    char text[1200];
    snprintf(text, sizeof text,
             "[laser]\ndevice =\n[can]\ninterface =\n[gpio]\nchip =\n[storage]\ndir = %s/store\n"
             "[link]\ndomain = 179\npartition = coslam-test-key-%ld\nconfig = file://%s\n[fleet]\nkey_file = %s\n",
             dir, (long)getpid(), xml, key);
    char err[4096];
    const char *hex = "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff";

    /* missing */
    assert_int_equal(run_robot(text, "--dry-run", err, sizeof err), 2);
    assert_non_null(strstr(err, "[fleet] key_file "));
    assert_non_null(strstr(err, "fleet.key: no such file; the robot does not start without its fleet key"));

    FILE *f = fopen(key, "w");
    assert_non_null(f);
    fprintf(f, "%s\n", hex);
    fclose(f);
    /* world-readable */
    assert_int_equal(chmod(key, 0644), 0);
    assert_int_equal(run_robot(text, "--dry-run", err, sizeof err), 2);
    assert_non_null(strstr(err, "fleet.key: accessible to others (mode 0644)"));
    assert_null(strstr(err, hex));
    /* world-accessible in any way, or group-writable */
    assert_int_equal(chmod(key, 0604), 0);
    assert_int_equal(run_robot(text, "", err, sizeof err), 2);
    assert_non_null(strstr(err, "accessible to others (mode 0604)"));
    assert_int_equal(chmod(key, 0620), 0);
    assert_int_equal(run_robot(text, "", err, sizeof err), 2);
    assert_non_null(strstr(err, "writable by its group (mode 0620)"));
    /* good: 0600, and 0640 (root:coslam as the package installs it) */
    assert_int_equal(chmod(key, 0600), 0);
    assert_int_equal(run_robot(text, "--dry-run", err, sizeof err), 0);
    assert_non_null(strstr(err, "authenticated with key id 1): up"));
    assert_null(strstr(err, hex));
    assert_null(strstr(err, "00112233"));
    assert_int_equal(chmod(key, 0640), 0);
    assert_int_equal(run_robot(text, "--dry-run", err, sizeof err), 0);
    /* owned by someone else, or readable by a group the robot is not in
     * (only where this test may chown: as root) */
    if (chown(key, 65534, (gid_t)-1) == 0) {
        assert_int_equal(run_robot(text, "--dry-run", err, sizeof err), 2);
        assert_non_null(strstr(err, "fleet.key: owned by uid 65534, neither root nor this robot's user"));
        assert_int_equal(chown(key, geteuid(), 65534), 0);
        assert_int_equal(run_robot(text, "--dry-run", err, sizeof err), 2);
        assert_non_null(strstr(err, "fleet.key: readable by group 65534, which this robot's user is not in"));
        assert_int_equal(chmod(key, 0600), 0); /* the group cannot read it: fine */
        assert_int_equal(run_robot(text, "--dry-run", err, sizeof err), 0);
        assert_int_equal(chown(key, geteuid(), getegid()), 0);
    }
    /* a NUL byte after the key, and something after that */
    f = fopen(key, "w");
    assert_non_null(f);
    fprintf(f, "%s", hex);
    fputc(0, f);
    fputs("junk\n", f);
    fclose(f);
    assert_int_equal(chmod(key, 0600), 0);
    assert_int_equal(run_robot(text, "--dry-run", err, sizeof err), 2);
    assert_non_null(strstr(err, "fleet.key: not a fleet key (a NUL byte in the file"));
    /* not a key */
    f = fopen(key, "w");
    assert_non_null(f);
    fprintf(f, "%.63s\n", hex); /* one digit short */
    fclose(f);
    assert_int_equal(run_robot(text, "--dry-run", err, sizeof err), 2);
    assert_non_null(strstr(err, "fleet.key: not a fleet key (expected 64 hexadecimal digits"));
    assert_null(strstr(err, "0011223344"));
    /* a directory */
    assert_int_equal(unlink(key), 0);
    assert_int_equal(mkdir(key, 0700), 0);
    assert_int_equal(run_robot(text, "--dry-run", err, sizeof err), 2);
    assert_non_null(strstr(err, "fleet.key: not a regular file"));
    assert_int_equal(rmdir(key), 0);

    /* no key file configured: runs, with the loud warning, no link */
    char none[1200];
    snprintf(none, sizeof none, "[laser]\ndevice =\n[can]\ninterface =\n[gpio]\nchip =\n[storage]\ndir = %s/store\n"
             "[robot]\nstatus_period_s = 0\n[fleet]\nkey_file =\n", dir);
    static char big[65536]; /* the final status line alone is over 2 KB */
    assert_int_equal(run_robot(none, "--once 5", big, sizeof big), 0);
    assert_non_null(strstr(big, "WARNING link: off (no fleet key)"));
    assert_non_null(strstr(big, "link_mode=off(no_fleet_key)"));
    assert_non_null(strstr(big, "WARNING: link: off (no fleet key)\n")); /* on the status line */

    char cmd[400];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    assert_int_equal(system(cmd), 0);
}

/* A [link] config naming a file that cannot be read: the link is down
 * (retried; the robot runs) and the reason names the key, the path and the
 * OS's reason (it was Cyclone's generic "refused"). */
static void binary_names_a_missing_link_config(void **state)
{
    (void)state;
#if !COSLAM_HAVE_DDS
    skip(); /* no DDS in this build: the link configuration is never read */
#endif
    const char *base = "[laser]\ndevice =\n[can]\ninterface =\n[gpio]\nchip =\n[fleet]\nkey_file =\n"
                       "[storage]\ndir = /nonexistent-coslam/link-store\n[link]\ninsecure = true\ndomain = 178\n";
    char text[600];
    char err[8192];
    snprintf(text, sizeof text, "%sconfig = file:///nonexistent-coslam/cyclonedds.xml\n", base);
    assert_int_equal(run_robot(text, "--dry-run", err, sizeof err), 0);
    if (strstr(err, "[link] config file:///nonexistent-coslam/cyclonedds.xml: cannot read "
                    "/nonexistent-coslam/cyclonedds.xml: No such file or directory (HAL_E_NOT_FOUND)") == NULL) {
        fprintf(stderr, "%s\n", err);
    }
    assert_non_null(strstr(err, "): down: [link] config file:///nonexistent-coslam/cyclonedds.xml: cannot read "
                                "/nonexistent-coslam/cyclonedds.xml: No such file or directory (HAL_E_NOT_FOUND); "
                                "retrying every"));
    /* a directory, second in a list after inline XML */
    snprintf(text, sizeof text, "%sconfig = <CycloneDDS/>, file:///tmp\n", base);
    assert_int_equal(run_robot(text, "--dry-run", err, sizeof err), 0);
    assert_non_null(strstr(err, "down: [link] config file:///tmp: cannot read /tmp: not a regular file (HAL_E_IO)"));
}

/* Write `text` to path. */
static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}

/* The landmark-log replay source refuses, at open with FILE:LINE, a robot
 * sighting of an id no robot of this build can have (it was dropped at
 * play time and said as a frame's capacity LIMIT), of this robot itself,
 * or of an id outside the configured fleet (both were played to the
 * meeting as a partner). Robot 0 of a fleet of 3 here. */
static void replay_log_refuses_a_foreign_robot_id(void **state)
{
    (void)state;
    char path[64];
    snprintf(path, sizeof path, "/tmp/coslam-lm-%d.log", (int)getpid());
    static robot_replay_t r;
    char msg[300];
    write_text(path, "Z 0.0 -1 2.0 0.1\nR 0.1 200 2.0 0.1\n");
    assert_int_equal(robot_replay_open(&r, path, 0, 0, 3, hal_clock_linux(), msg, sizeof msg), HAL_E_CORRUPT);
    assert_non_null(strstr(msg, ":2: other_robot_id 200 is not a robot id of this build"));
    write_text(path, "Z 0.0 -1 2.0 0.1\n# robot 0 sees itself\nR 0.1 0 2.0 0.1\n");
    assert_int_equal(robot_replay_open(&r, path, 0, 0, 3, hal_clock_linux(), msg, sizeof msg), HAL_E_CORRUPT);
    assert_non_null(strstr(msg, path));
    assert_non_null(strstr(msg, ":3: other_robot_id 0 is this robot's own id ([robot] id = 0)"));
    write_text(path, "R 0.1 2 2.0 0.1\nR 0.2 3 2.0 0.1\n");
    assert_int_equal(robot_replay_open(&r, path, 0, 0, 3, hal_clock_linux(), msg, sizeof msg), HAL_E_CORRUPT);
    assert_non_null(strstr(msg, ":2: other_robot_id 3 is not in the fleet ([robot] fleet_size = 3: ids 0 .. 2)"));
    /* the fleet's other robots are good */
    write_text(path, "Z 0.0 -1 2.0 0.1\nR 0.1 1 2.0 0.1\nR 0.1 2 3.0 0.2\n");
    assert_int_equal(robot_replay_open(&r, path, 0, 0, 3, hal_clock_linux(), msg, sizeof msg), HAL_OK);
    robot_replay_close(&r);
    /* robot 2 may see robot 0 */
    write_text(path, "R 0.1 0 2.0 0.1\n");
    assert_int_equal(robot_replay_open(&r, path, 0, 2, 3, hal_clock_linux(), msg, sizeof msg), HAL_OK);
    robot_replay_close(&r);
    assert_int_equal(unlink(path), 0);
}

int main(int argc, char **argv)
{
    unsetenv("CYCLONEDDS_URI"); /* the DDS configuration is the test's own */
    if (argc > 1) {
        cmocka_set_test_filter(argv[1]);
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(default_file_loads_and_is_the_default),
        cmocka_unit_test(print_reads_back),
        cmocka_unit_test(link_keys_defaults_and_round_trip),
        cmocka_unit_test(meeting_noise_comes_from_slam),
        cmocka_unit_test(closure_keys_reach_the_filter),
        cmocka_unit_test(watchdog_keys_reach_the_drive),
        cmocka_unit_test(bad_files_name_file_and_line),
        cmocka_unit_test(binary_says_the_drive_watchdog),
        cmocka_unit_test(binary_exits_2_with_file_and_line),
        cmocka_unit_test(binary_refuses_a_bad_fleet_key),
        cmocka_unit_test(binary_names_a_missing_link_config),
        cmocka_unit_test(replay_log_refuses_a_foreign_robot_id),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
