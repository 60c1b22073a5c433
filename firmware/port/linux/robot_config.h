/*
 * robot_config.h - the settings of coslam-robot: one INI file (libinih),
 * default /etc/coslam/robot.ini, documented key by key in robot.ini beside
 * this file and in docs/robot.md.
 *
 * Sections: [robot] identity, fleet, periods; [laser] [can] [gpio]
 * [camera] [link] [storage] [fleet] the devices; [filter] [slam] [merge]
 * [behaviour] the robot node (app/robot_node.h). Every key is optional
 * (defaults: robot_config_default()). [slam] is the shared key table of
 * app/slam_params_ini.h, the same one coslam-replay reads; the meeting's
 * robot-sighting noise is taken from it (meeting_config_noise_from), so
 * there is one settings source for the noise. [filter] and [merge] use
 * coslam-replay's key names where the two tools share a setting.
 *
 * Errors: an unknown section (refused at its header, keys in it or not) or
 * key, a section header repeated (refused
 * at the second, naming the first's line), a key given twice (libinih also reads
 * an indented line as a continuation of the key above: that is a second
 * value, refused), a line longer than 198 characters, a value with a byte
 * outside printable ASCII and tab (the message names its position, never
 * echoes it), a text value whose "key = value" line would not fit when
 * written back, a value that is not a number (or not one of the words a
 * key accepts), a value outside its domain, or two keys that contradict
 * each other are reported as "FILE:LINE: [section] key: reason" (the line
 * of the later key for a contradiction); the first error
 * wins. Text of the file quoted in a message (keys, section names, values)
 * has every byte outside printable ASCII as \xNN. The caller exits with
 * status 2 (robot_main.c).
 *
 * No heap: robot_config_t is caller-owned (about 3 KB plus
 * robot_node_config_t). Not thread-safe (one load at a time).
 */
#ifndef COSLAM_PORT_ROBOT_CONFIG_H
#define COSLAM_PORT_ROBOT_CONFIG_H

#include <stdint.h>
#include <stdio.h>

#include "app/robot_node.h"
#include "coslam/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Default configuration file. */
#define ROBOT_CONFIG_DEFAULT_PATH "/etc/coslam/robot.ini"
/** Longest path or device name in the file [characters, without NUL]. */
#define ROBOT_CONFIG_PATH_MAX 255u
/** Longest message of a load error [characters, without NUL]. */
#define ROBOT_CONFIG_MSG_MAX 511u
/** Most [link] peers. */
#define ROBOT_CONFIG_MAX_PEERS 16u
/** [link] topic default: HAL_LINK_DDS_DEFAULT_TOPIC, ROS 2 topic /coslam/map
 *  (robot_link.c checks the two agree in DDS builds). */
#define ROBOT_CONFIG_DEFAULT_TOPIC "rt/coslam/map"

typedef struct {
    /* [robot] */
    uint8_t robot_id;              /**< id, < fleet_size; also the link id */
    uint8_t fleet_size;            /**< robots in the team, 2..COSLAM_MAX_ROBOTS */
    uint32_t step_period_us;       /**< control period of the main loop [us] */
    double status_period_s;        /**< status line on stderr every this [s]; 0: off */
    double snapshot_period_s;      /**< map snapshot every this [s]; 0: only at shutdown */
    double retry_period_s;         /**< failed devices reopened (and the laser reconnected) every this [s] */
    /* [laser] */
    char laser_device[ROBOT_CONFIG_PATH_MAX + 1u];  /**< serial device of the URG; "" = none */
    uint32_t laser_baud;
    /* [can] */
    char can_interface[ROBOT_CONFIG_PATH_MAX + 1u]; /**< SocketCAN interface; "" = none */
    /* [gpio] */
    char gpio_chip[ROBOT_CONFIG_PATH_MAX + 1u];     /**< libgpiod chip; "" = none */
    uint8_t gpio_required;         /**< 1: no motion while the bumper / e-stop roles are missing */
    /* [camera] */
    char camera_device[ROBOT_CONFIG_PATH_MAX + 1u]; /**< V4L2 camera device (robot_camera.h); "" = none */
    uint32_t camera_width_px;      /**< frame size asked of the camera and given to the detector */
    uint32_t camera_height_px;
    uint8_t camera_mjpeg_first;    /**< 1: ask for MJPEG before YUYV (a camera whose YUYV is slow) */
    char camera_colour_table[ROBOT_CONFIG_PATH_MAX + 1u]; /**< colour table file (vision/vision.h) */
    char camera_range_model[ROBOT_CONFIG_PATH_MAX + 1u];  /**< range model file; "" = pinhole model */
    uint32_t camera_stall_us;      /**< no frame for this long while up: reopened; 0 = never */
    char camera_replay_log[ROBOT_CONFIG_PATH_MAX + 1u]; /**< test/bench source: landmark log; "" = none */
    uint8_t camera_replay_loop;    /**< 1: start the log again at its end */
    /* [link]: the Cyclone DDS link (robot_link.h has the policy) */
    uint32_t link_domain;          /**< DDS domain id, 0..232 (ROS_DOMAIN_ID) */
    char link_peers[ROBOT_CONFIG_PATH_MAX + 1u];    /**< comma-separated unicast peer addresses
                                                         (checked: at most ROBOT_CONFIG_MAX_PEERS,
                                                         [A-Za-z0-9.:_-] and [ ]); "" = multicast */
    char link_partition[ROBOT_CONFIG_PATH_MAX + 1u];/**< DDS partition; "" = the default one (ROS 2's) */
    char link_topic[ROBOT_CONFIG_PATH_MAX + 1u];    /**< DDS topic (ROBOT_CONFIG_DEFAULT_TOPIC) */
    char link_config[ROBOT_CONFIG_PATH_MAX + 1u];   /**< extra Cyclone configuration (XML or
                                                         file:// URI); "" = none */
    uint32_t link_history_depth;   /**< DDS KEEP_LAST depth [samples] */
    uint8_t link_insecure;         /**< 1: DDS without authentication (explicit opt-in) */
    /* [storage] */
    char storage_dir[ROBOT_CONFIG_PATH_MAX + 1u];   /**< map snapshots go here */
    /* [fleet] */
    char fleet_key_file[ROBOT_CONFIG_PATH_MAX + 1u];/**< fleet key path (authentication; never
                                                         logged); "" = none: no link */
    uint8_t fleet_key_id;          /**< version of that key, sent in the clear (0..255) */
    double fleet_window_s;         /**< authentication time window [s] (fleet clocks within it) */
    /* end-to-end tests only (docs/e2e.md), set from the command line, no
     * INI keys: inherited file descriptors from the device server */
    int can_fd;                    /**< --can-fd: SOCK_SEQPACKET carrying struct can_frame
                                        instead of a SocketCAN interface; -1 = none */
    int camera_live_fd;            /**< --sightings-fd: the live sighting stream
                                        (robot_live_open, a camera stand-in); -1 = none */
    int gpio_fd;                   /**< --gpio-fd: line states instead of a GPIO chip
                                        (robot_gpio_fd.h); -1 = none */
    /* everything the robot node takes; robot_id, n_robots, filter.robot_id,
     * filter_period_us, retry_period_us, the meeting's robot-sighting noise
     * and the degraded-mode flags are derived at the end of the load */
    robot_node_config_t node;
} robot_config_t;

/** The defaults (robot.ini beside this file writes each one out): robot 0
 *  of 2, 10 ms step, status every 10 s, snapshot every 30 s, retry every
 *  5 s, /dev/ttyACM0 at 115200 baud, can0, gpiochip0 (bumper line 0,
 *  e-stop line 1 active low, LED line 2, required), no camera (when one is
 *  configured: 320x240, YUYV first, the packaged colour table and range
 *  model in /usr/share/coslam/vision, reopened after 2 s without a frame), DDS domain
 *  0 with multicast discovery, the default partition, topic
 *  rt/coslam/map, depth 32, authenticated; /var/lib/coslam,
 *  /etc/coslam/fleet.key with key id 1 and a 30 s window, and the node defaults of
 *  robot_node_config_default() with the degraded modes on. */
void robot_config_default(robot_config_t *cfg);

/**
 * Apply the INI file `path` on top of *cfg (start from robot_config_default).
 * Returns COSLAM_OK; COSLAM_E_ARG (the file is wrong: msg holds
 * "FILE:LINE: ...", "FILE: cannot open ...", "FILE: not a regular file
 * ..." or "FILE: read error after line N"); COSLAM_E_ARG also for NULL
 * arguments. On error *cfg holds the keys read before the error.
 */
coslam_status_t robot_config_load(robot_config_t *cfg, const char *path, char *msg, size_t msg_cap);

/** Same from text; `name` stands for the file name in messages. */
coslam_status_t robot_config_load_string(robot_config_t *cfg, const char *text, const char *name, char *msg,
                                         size_t msg_cap);

/** Write the whole configuration as an INI file that robot_config_load
 *  reads back to the same struct (doubles with 17 digits, floats with 9). */
void robot_config_print(const robot_config_t *cfg, FILE *out);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_PORT_ROBOT_CONFIG_H */
