#include "app/robot_node.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

robot_node_config_t robot_node_config_default(uint8_t robot_id, uint8_t n_robots)
{
    robot_node_config_t c;
    memset(&c, 0, sizeof c);
    c.robot_id = robot_id;
    c.n_robots = n_robots;
    c.filter = slam_filter_config_default();
    c.filter.robot_id = robot_id;
    c.meeting = meeting_config_default();
    c.behaviour = behaviour_config_default();
    obstacle_params_default(&c.obstacle);
    occ_grid_params_default(&c.grid);
    c.grid_origin_m.x = -0.5 * COSLAM_GRID_CELLS_X * OCC_GRID_CELL_M;
    c.grid_origin_m.y = -0.5 * COSLAM_GRID_CELLS_Y * OCC_GRID_CELL_M;
    c.laser_in_robot.x = 0.12;
    c.laser_in_robot.y = 0.0;
    c.laser_in_robot.theta = 0.0;
    c.laser_fov_rad = 140.0 * COSLAM_PI / 180.0;
    urg_scip2_config_default(&c.urg);
    c.drive = cia402_omni_config_default();
    c.gpio.n_bumpers = 1U;
    c.gpio.bumpers[0].line = 0U;
    c.gpio.bumpers[0].active_low = false;
    c.gpio.bumper_debounce_us = 5000U;
    c.gpio.has_estop = true;
    c.gpio.estop.line = 1U;
    c.gpio.estop.active_low = true;
    c.gpio.estop_release_us = 50000U;
    c.gpio.n_leds = 1U;
    c.gpio.leds[0].line = 2U;
    c.gpio.leds[0].active_low = false;
    c.status_led = 0U;
    c.filter_period_us = 100000U;
    c.scan_max_age_us = 300000U;
    c.retry_period_us = 1000000U;
    c.laser_optional = 0U;
    c.laser_lost_us = 2000000U;
    c.blind_max_turn_radps = 0.3;
    c.gpio_optional = 0U;
    c.motion_without_gpio = 0U;
    c.drive_absent = 0U;
    c.health = health_config_default();
    return c;
}

coslam_status_t robot_node_init(robot_node_t *n, const robot_node_config_t *cfg, const robot_node_io_t *io)
{
    if (n == NULL || cfg == NULL || io == NULL || io->clock == NULL || io->laser == NULL || io->can == NULL ||
        io->gpio == NULL || io->link == NULL || io->sightings == NULL) {
        return COSLAM_E_ARG;
    }
    if (cfg->n_robots < 2U || cfg->n_robots > COSLAM_MAX_ROBOTS || cfg->robot_id >= cfg->n_robots ||
        cfg->filter_period_us == 0U || !pose2_is_finite(cfg->laser_in_robot) || !isfinite(cfg->laser_fov_rad) ||
        !(cfg->laser_fov_rad > 0.0) || !isfinite(cfg->grid_origin_m.x) || !isfinite(cfg->grid_origin_m.y) ||
        !(isfinite(cfg->blind_max_turn_radps) && cfg->blind_max_turn_radps >= 0.0)) {
        return COSLAM_E_ARG;
    }
    memset(n, 0, sizeof *n);
    n->cfg = *cfg;
    n->cfg.filter.robot_id = cfg->robot_id;
    n->cfg.obstacle.cruise_speed_mps = cfg->behaviour.cruise_mps;
    n->io = *io;
    coslam_status_t st = urg_scip2_init(&n->urg, io->laser, &n->cfg.urg);
    if (st == COSLAM_OK) {
        st = cia402_omni_init(&n->drive, &n->cfg.drive, io->can);
    }
    if (st == COSLAM_OK) {
        st = occ_grid_init(&n->grid, &n->cfg.grid, cfg->grid_origin_m.x, cfg->grid_origin_m.y);
    }
    if (st == COSLAM_OK) {
        const pose2_t origin = {0.0, 0.0, 0.0};
        st = slam_filter_init(&n->filter, &n->cfg.filter, origin);
    }
    if (st == COSLAM_OK) {
        st = meeting_init(&n->meeting, &n->cfg.meeting, cfg->robot_id, cfg->n_robots);
        meeting_set_grid(&n->meeting, &n->grid); /* occlusion for the merge check */
    }
    if (st == COSLAM_OK) {
        st = behaviour_init(&n->behaviour, &n->cfg.behaviour);
    }
    if (st == COSLAM_OK) {
        st = health_init(&n->health, &n->cfg.health);
    }
    if (st != COSLAM_OK) {
        return COSLAM_E_ARG;
    }
    if (cfg->gpio.n_bumpers > 0U || cfg->gpio.has_estop || cfg->gpio.n_leds > 0U) {
        const coslam_status_t gs = robot_node_gpio_attach(n);
        if (gs == COSLAM_E_ARG || (gs != COSLAM_OK && !cfg->gpio_optional)) {
            return gs;
        }
    }
    /* without a laser to wait for, the drive comes up at once */
    n->state = cfg->laser_optional ? ROBOT_NODE_DRIVE_UP : ROBOT_NODE_LASER_UP;
    return COSLAM_OK;
}

static int gpio_roles_configured(const robot_node_t *n)
{
    return n->cfg.gpio.n_bumpers > 0U || n->cfg.gpio.has_estop || n->cfg.gpio.n_leds > 0U;
}

coslam_status_t robot_node_gpio_attach(robot_node_t *n)
{
    if (n == NULL) {
        return COSLAM_E_ARG;
    }
    if (n->gpio_ok || !gpio_roles_configured(n)) {
        return COSLAM_OK;
    }
    const hal_status_t hs = gpio_roles_init(&n->gpio, &n->cfg.gpio, n->io.gpio, n->io.clock);
    if (hs == HAL_E_ARG) {
        return COSLAM_E_ARG;
    }
    if (hs != HAL_OK) {
        n->ctr.gpio_attach_failures++;
        return COSLAM_E_UNSUPPORTED;
    }
    n->gpio_ok = 1;
    return COSLAM_OK;
}

void robot_node_gpio_detach(robot_node_t *n)
{
    if (n != NULL && n->gpio_ok) {
        gpio_roles_deinit(&n->gpio);
        n->gpio_ok = 0;
    }
}

int robot_node_gpio_attached(const robot_node_t *n)
{
    return n->gpio_ok || !gpio_roles_configured(n);
}

void robot_node_hold(robot_node_t *n, int hold)
{
    if (n != NULL) {
        n->hold = hold != 0;
    }
}

int robot_node_laser_up(const robot_node_t *n)
{
    return n->laser_up;
}

uint32_t robot_node_msg_seq(const robot_node_t *n)
{
    return n->meeting.tx_seq;
}

coslam_status_t robot_node_restore(robot_node_t *n, const map_estimate_t *map, uint32_t msg_seq)
{
    if (n == NULL || map == NULL) {
        return COSLAM_E_ARG;
    }
    /* the number belongs to the link, not to the map: kept even when the
     * map is refused, or the peers would take every message for a replay */
    n->meeting.tx_seq = msg_seq;
    const coslam_status_t st = slam_filter_seed(&n->filter, &n->cfg.filter, map);
    if (st != COSLAM_OK && st != COSLAM_E_CAPACITY) {
        if (!pose2_is_finite(map->pose)) {
            const pose2_t origin = {0.0, 0.0, 0.0};
            (void)slam_filter_init(&n->filter, &n->cfg.filter, origin);
        }
        return COSLAM_E_ARG;
    }
    return st;
}

/* The laser's connect, one step of it: SCIP 2.0, parameters, then
 * continuous scans over the configured field of view, each command begun
 * once the last one's reply has come (urg_scip2_begin_*, urg_scip2_poll:
 * nothing waits, so the control loop goes on meanwhile). A reply must be
 * whole within twice the driver's reply timeout of its command (a PP
 * reply is about 250 bytes, 0.13 s at 19,200 baud). Returns 1 connected, 0
 * still waiting, -1 failed (*why: the driver's code; begun again from
 * SCIP2.0 by the next call). */
static int laser_connect_step(robot_node_t *n, coslam_status_t *why)
{
    for (;;) {
        coslam_status_t st = COSLAM_OK;
        if (!urg_scip2_pending(&n->urg)) {
            if (n->laser_phase == 0U) {
                st = urg_scip2_begin_enter_scip2(&n->urg);
            } else if (n->laser_phase == 1U) {
                st = urg_scip2_begin_read_params(&n->urg);
            } else {
                const urg_scip2_params_t *p = urg_scip2_params(&n->urg);
                const double half_steps = 0.5 * n->cfg.laser_fov_rad / (COSLAM_TWO_PI / (double)p->ares);
                const uint32_t half = (uint32_t)fmin(half_steps, 4096.0);
                const uint32_t first = p->afrt > p->amin + half ? p->afrt - half : p->amin;
                const uint32_t last = p->afrt + half < p->amax ? p->afrt + half : p->amax;
                st = urg_scip2_begin_start_md(&n->urg, (uint16_t)first, (uint16_t)last, 1U, 0U, 0U);
            }
            n->laser_cmd_at_us = n->now_us;
            if (st != COSLAM_OK) {
                n->laser_phase = 0U;
                *why = st;
                return -1;
            }
        }
        st = urg_scip2_poll(&n->urg);
        if (st == COSLAM_E_URG_TIMEOUT) {
            if (n->now_us - n->laser_cmd_at_us <= 2U * (uint64_t)n->cfg.urg.reply_timeout_us) {
                return 0;
            }
            urg_scip2_abandon(&n->urg); /* counted as the driver's timeout */
        }
        if (st != COSLAM_OK) {
            n->laser_phase = 0U;
            *why = st;
            return -1;
        }
        if (++n->laser_phase == 3U) {
            n->laser_phase = 0U;
            return 1;
        }
    }
}

/* The drives' watchdog time [us]; 0 without it. */
static uint64_t drive_watchdog_us(const robot_node_t *n)
{
    const cia402_drive_config_t *d = &n->cfg.drive.drive;
    return d->master_node_id != 0U ? (uint64_t)d->master_timeout_ms * 1000U : 0U;
}

/* The drives went unpolled from `from` to `to` (no master heartbeat): longer
 * than their watchdog, they have stopped the base by themselves. */
static void note_gap(robot_node_t *n, uint64_t from, uint64_t to)
{
    const uint64_t wd = drive_watchdog_us(n);
    /* not while shutting down: the base is being stopped anyway (the
     * laser's QT there may block a reply timeout) */
    if (wd == 0U || !n->drive_started || n->state == ROBOT_NODE_SHUTDOWN || to <= from || to - from <= wd) {
        return;
    }
    n->ctr.stalls++;
    n->stall_at_us = to;
    n->stall_us = to - from > UINT32_MAX ? UINT32_MAX : (uint32_t)(to - from);
}

/* The laser driver's search count since the last call into the node's
 * total. Called every step, so the 32-bit count cannot wrap twice between
 * calls (a step looks at a few receive buffers, not 4 GiB), and before
 * the driver is reset. */
static void laser_rx_search_add(robot_node_t *n)
{
    const uint32_t now = urg_scip2_rx_search_bytes(&n->urg);
    n->laser_rx_search_bytes += (uint32_t)(now - n->laser_rx_search_seen);
    n->laser_rx_search_seen = now;
}

/* laser_optional: connect in the background, notice a laser that went
 * silent. The connect does not wait (laser_connect_step): the base goes on
 * meanwhile, without translating while no scan comes (scan_max_age_us). */
static coslam_status_t laser_background(robot_node_t *n)
{
    if (n->laser_up) {
        const uint64_t last = n->scan_us > n->laser_alive_us ? n->scan_us : n->laser_alive_us;
        if (n->cfg.laser_lost_us == 0U || n->now_us - last <= n->cfg.laser_lost_us) {
            return COSLAM_OK;
        }
        n->laser_up = 0;
        n->ctr.laser_lost++;
        n->laser_retry_at_us = n->now_us;
        /* a fresh driver state (receive buffer, streaming flag); its
         * counters go on, its search count in the node's total */
        const urg_scip2_stats_t keep = *urg_scip2_stats(&n->urg);
        laser_rx_search_add(n);
        (void)urg_scip2_init(&n->urg, n->io.laser, &n->cfg.urg);
        n->urg.stats = keep;
        n->laser_rx_search_seen = 0U;
        n->laser_phase = 0U;
    }
    if (n->now_us < n->laser_retry_at_us) {
        return COSLAM_OK;
    }
    coslam_status_t st = COSLAM_OK;
    const int r = laser_connect_step(n, &st);
    if (r == 0) {
        return COSLAM_OK;
    }
    if (r > 0) {
        n->laser_up = 1;
        n->laser_alive_us = n->now_us;
        return COSLAM_OK;
    }
    n->ctr.laser_connect_failures++;
    n->laser_retry_at_us = n->now_us + n->cfg.retry_period_us;
    return st;
}

static void flush_prediction(robot_node_t *n)
{
    const odo_increment_t u = n->odo_pending;
    if (u.dx != 0.0 || u.dy != 0.0 || u.dtheta != 0.0) {
        const coslam_status_t st = slam_filter_predict(&n->filter, u, 1e-6 * (double)(n->now_us - n->last_predict_us));
        /* a full pool is counted by the filter; a prediction held while an
         * EKF-SLAM merge runs in parts is applied after it (held_failures) */
        if (st != COSLAM_OK && st != COSLAM_E_CAPACITY && st != COSLAM_E_MERGE_PENDING) {
            n->ctr.filter_errors++;
        }
    }
    n->odo_pending.dx = 0.0;
    n->odo_pending.dy = 0.0;
    n->odo_pending.dtheta = 0.0;
    n->last_predict_us = n->now_us;
}

static void take_odometry(robot_node_t *n)
{
    odo_increment_t u;
    if (cia402_omni_take_odometry(&n->drive, &u, NULL) != COSLAM_OK) {
        return;
    }
    if (!motion_is_finite(u)) {
        n->ctr.odometry_errors++;
        return;
    }
    n->odo_pose = motion_apply(n->odo_pose, u);
    n->travel_m += motion_travel_m(u, n->cfg.filter.slam.base_radius_m);
    n->odo_pending = omni_kinematics_compose(n->odo_pending, u);
}

/* One scan: occupancy grid at the SLAM pose; kept for the behaviour. */
static void use_scan(robot_node_t *n)
{
    size_t np = 0;
    if (urg_scip2_scan_polar(urg_scip2_params(&n->urg), &n->scan, URG_SCIP2_POLAR_CODE0_NO_RETURN, n->scan_range_m,
                             n->scan_angle_rad, COSLAM_MAX_SCAN_POINTS, &np) != COSLAM_OK) {
        n->ctr.scan_errors++;
        return;
    }
    n->ctr.scans++;
    pose2_t map_pose;
    cov3_t cov;
    slam_filter_pose(&n->filter, &map_pose, &cov);
    const pose2_t sensor = pose2_compose(map_pose, n->cfg.laser_in_robot);
    health_on_scan(&n->health, &n->grid, sensor, n->scan_range_m, n->scan_angle_rad, np);
    if (occ_grid_integrate_scan(&n->grid, sensor, n->scan_range_m, n->scan_angle_rad, np, NULL) == COSLAM_E_CAPACITY) {
        n->ctr.grid_out_of_grid++;
    }
    n->scan_n_points = 0;
    for (size_t i = 0; i < np; ++i) {
        const double r = n->scan_range_m[i];
        if (isfinite(r) && r > 0.0) {
            const point2_t q = {r * cos(n->scan_angle_rad[i]), r * sin(n->scan_angle_rad[i])};
            n->scan_points_m[n->scan_n_points++] = pose2_apply(n->cfg.laser_in_robot, q);
        }
    }
    health_on_motion_scan(&n->health, n->now_us, n->odo_pose, n->scan_points_m, n->scan_n_points);
    n->ctr.diverged = n->health.episodes;
    n->scan_n = np;
    n->scan_us = n->now_us;
    n->scan_odo_pose = n->odo_pose;
}

/* What the camera could see this frame (view.h): the last scan's obstacle
 * points moved by the odometry since, if the scan is at most
 * scan_max_age_us old; otherwise no profile and every miss counts. */
static void set_view(robot_node_t *n)
{
    view_profile_clear(&n->view);
    if (n->scan_n > 0U && n->now_us - n->scan_us <= n->cfg.scan_max_age_us) {
        const pose2_t since = pose2_compose(pose2_inverse(n->odo_pose), n->scan_odo_pose);
        if (view_profile_build(&n->view, n->scan_points_m, n->scan_n_points, since) != COSLAM_OK) {
            view_profile_clear(&n->view);
        }
    }
    if (n->view.valid) {
        n->ctr.views++;
    }
    slam_filter_set_view(&n->filter, &n->view);
}

/* Every scan that arrived since the last step (normally none or one). A
 * failed read empties the scan buffer, so each good scan is converted at once
 * (the polar arrays keep the last good one). */
static void read_laser(robot_node_t *n)
{
    for (int i = 0; i < 4; ++i) {
        const coslam_status_t st = urg_scip2_read_scan(&n->urg, &n->scan, 0U);
        if (st == COSLAM_OK) {
            use_scan(n);
            continue;
        }
        if (st != COSLAM_E_URG_TIMEOUT && st != COSLAM_E_EMPTY) {
            n->ctr.scan_errors++;
        }
        break;
    }
}

static void read_sightings(robot_node_t *n)
{
    const hal_status_t hs = sighting_source_next_frame(n->io.sightings, &n->frame, 0U);
    if (hs == HAL_E_TIMEOUT) {
        return;
    }
    if (hs != HAL_OK) {
        n->ctr.frame_errors++;
        return;
    }
    n->ctr.frames++;
    n->ctr.sightings_dropped += n->frame.dropped;
    flush_prediction(n);
    const int nz = n->frame.n_landmarks <= COSLAM_MAX_SIGHTINGS ? (int)n->frame.n_landmarks : COSLAM_MAX_SIGHTINGS;
    /* the monitor reads the state the update applies to: a merge or held
     * inputs that must finish first are finished before it looks */
    if (!slam_filter_update_prepare(&n->filter, nz)) {
        health_before_update(&n->health, &n->filter, &n->grid);
    }
    set_view(n);
    const coslam_status_t st = slam_filter_update_apply(&n->filter, n->frame.landmarks, nz);
    /* held while an EKF-SLAM merge runs in parts (slam_filter inputs_held):
     * no update to judge yet */
    if (st != COSLAM_E_MERGE_PENDING) {
        if (st != COSLAM_OK && st != COSLAM_E_CAPACITY) {
            n->ctr.filter_errors++;
        }
        health_after_update(&n->health, &n->filter, n->frame.landmarks, nz);
        n->ctr.diverged = n->health.episodes;
    }
    const unsigned nr = n->frame.n_robots <= COSLAM_MAX_ROBOTS ? n->frame.n_robots : COSLAM_MAX_ROBOTS;
    for (unsigned i = 0; i < nr; ++i) {
        const robot_seen_t *r = &n->frame.robots[i];
        /* an id no partner has (outside the team, or this robot's own) and
         * a sighting the meeting refuses are lost: counted, never silent */
        if (r->robot_id >= n->cfg.n_robots || r->robot_id == n->cfg.robot_id || !(isfinite(r->range_m) && r->range_m > 0.0) ||
            !isfinite(r->bearing_rad)) {
            n->ctr.robot_sightings_refused++;
            continue;
        }
        /* COSLAM_E_ARG is also a failed send's export or encoding, which the
         * meeting counts in send_failures: refused only if that did not grow */
        const uint32_t send_failures = n->meeting.ctr.send_failures;
        const coslam_status_t ms = meeting_on_sighting(&n->meeting, &n->filter, n->io.link, n->now_us, r->robot_id,
                                                       r->range_m, r->bearing_rad, n->frame.stamp_us, n->odo_pose,
                                                       n->travel_m);
        if (ms == COSLAM_E_ARG && n->meeting.ctr.send_failures == send_failures) {
            n->ctr.robot_sightings_refused++;
        }
    }
}

/* The peer to face: the nearest one in view, preferring peers not merged yet;
 * its bearing moved to now with the own rotation since the sighting. */
static int peer_in_view(const robot_node_t *n, double *bearing_now)
{
    const uint64_t timeout_us = (uint64_t)(n->cfg.behaviour.peer_timeout_s * 1e6);
    double best_key = INFINITY;
    int found = 0;
    for (uint8_t k = 0; k < n->cfg.n_robots; ++k) {
        meeting_sighting_t s;
        if (k == n->cfg.robot_id || meeting_last_sighting(&n->meeting, k, &s) != COSLAM_OK ||
            n->now_us - s.stamp_us > timeout_us) {
            continue;
        }
        const double key = s.range_m + (n->meeting.peer[k].merged ? 1000.0 : 0.0);
        if (key < best_key) {
            best_key = key;
            found = 1;
            *bearing_now = angle_wrap(s.bearing_rad - angle_wrap(n->odo_pose.theta - s.odo_pose.theta));
        }
    }
    return found;
}

static void update_gpio(robot_node_t *n, int *stop, int *bumped)
{
    *stop = 0;
    *bumped = 0;
    if (!n->gpio_ok) {
        return;
    }
    (void)gpio_roles_update(&n->gpio, &n->gpio_status);
    *stop = n->gpio_status.stop_requested ? 1 : 0;
    if (n->gpio_status.bumpers_latched != 0U &&
        (n->gpio_status.bumpers_latched & n->gpio_status.bumpers_pressed) == 0U) {
        if (gpio_roles_bumper_ack(&n->gpio, GPIO_ROLES_ALL_BUMPERS) == HAL_OK) {
            n->ctr.bumper_acks++;
            *bumped = 1;
        }
    }
}

static void set_led(robot_node_t *n, int stop)
{
    if (!n->gpio_ok || n->cfg.gpio.n_leds == 0U) {
        return;
    }
    gpio_roles_pattern_t pat = GPIO_ROLES_PATTERN_BLINK_SLOW;
    if (n->state == ROBOT_NODE_RUN) {
        pat = stop ? GPIO_ROLES_PATTERN_BLINK_FAST : GPIO_ROLES_PATTERN_HEARTBEAT;
    } else if (n->state == ROBOT_NODE_FAULT) {
        pat = GPIO_ROLES_PATTERN_BLINK_FAST;
    }
    (void)gpio_roles_led_set(&n->gpio, n->cfg.status_led, pat);
}

/* Bring-up, enable, fault handling. Returns the drive error worth reporting. */
static coslam_status_t run_drive(robot_node_t *n)
{
    coslam_status_t result = COSLAM_OK;
    if (n->cfg.drive_absent) {
        return COSLAM_OK; /* no drives on purpose: nothing is at fault */
    }
    if (!n->drive_started) {
        if (cia402_omni_start(&n->drive, n->now_us) != COSLAM_OK) {
            n->ctr.drive_errors++;
            return COSLAM_E_DRIVE_BUS;
        }
        n->drive_started = 1;
    }
    const coslam_status_t st = cia402_omni_poll(&n->drive, n->now_us);
    if (st == COSLAM_E_DRIVE_FAULT) {
        /* one fault is counted once, until the drive reports clear: an EMCY's
         * reset clears asynchronously, so the polls right after the reset
         * still report it */
        if (!n->drive_fault_latched) {
            n->drive_fault_latched = 1;
            n->ctr.drive_faults++;
            result = st;
        }
        /* a reset just sent gets a retry period to clear while the drive
         * comes up again (not once it runs: a fault then is a new one) */
        const int after_reset = n->state == ROBOT_NODE_DRIVE_UP && n->fault_reset_at_us != 0U;
        const int clearing = after_reset && n->now_us - n->fault_reset_at_us < n->cfg.retry_period_us;
        if (n->state != ROBOT_NODE_FAULT && !clearing) {
            n->state = ROBOT_NODE_FAULT;
            /* a reset that did not clear it has had its retry period: the
             * next one at once, so resets go every retry_period_us */
            n->retry_at_us = after_reset ? n->now_us : n->now_us + n->cfg.retry_period_us;
            /* a fault found within a second of this node's own stall is the
             * drives' watchdog (or this side's supervision seeing the stale
             * frames): the stall explains it, so the reset goes at once;
             * a reset that does not clear it falls back to the rule above */
            if (!after_reset && n->stall_at_us != 0U && n->now_us - n->stall_at_us <= 1000000U) {
                n->retry_at_us = n->now_us;
                n->ctr.stall_resets++;
                n->stall_at_us = 0U;
            }
        }
    } else if (st != COSLAM_OK) {
        n->ctr.drive_errors++;
    } else {
        n->drive_fault_latched = 0;
    }
    if (n->state == ROBOT_NODE_FAULT && n->now_us >= n->retry_at_us) {
        (void)cia402_omni_fault_reset(&n->drive, n->now_us);
        n->fault_reset_at_us = n->now_us;
        n->state = ROBOT_NODE_DRIVE_UP;
    }
    if (n->state == ROBOT_NODE_DRIVE_UP && cia402_omni_is_running(&n->drive)) {
        if (cia402_omni_is_enabled(&n->drive)) {
            n->state = ROBOT_NODE_RUN;
            n->fault_reset_at_us = 0U; /* running: no reset is clearing any more */
        } else {
            (void)cia402_omni_enable(&n->drive, 1);
        }
    }
    return result;
}

int robot_node_idle(robot_node_t *n)
{
    return slam_filter_idle(&n->filter);
}

coslam_status_t robot_node_step(robot_node_t *n)
{
    if (n == NULL) {
        return COSLAM_E_ARG;
    }
    uint64_t now;
    if (hal_clock_now_us(n->io.clock, &now) != HAL_OK) {
        return COSLAM_E_ARG;
    }
    n->now_us = now;
    if (n->last_step_us != 0U) {
        note_gap(n, n->last_step_us, now); /* a late step: the process stalled between steps */
    }
    n->last_step_us = now;
    laser_rx_search_add(n);
    if (n->state == ROBOT_NODE_SHUTDOWN) {
        if (n->drive_started) {
            (void)cia402_omni_poll(&n->drive, now); /* let the disable sequence finish */
        }
        return COSLAM_OK;
    }
    n->ctr.steps++;
    coslam_status_t result = COSLAM_OK;
    int stop = 0;
    int bumped = 0;
    update_gpio(n, &stop, &bumped);
    if (stop) {
        n->ctr.stop_steps++;
    }

    if (n->cfg.laser_optional) {
        result = laser_background(n);
    } else if (n->state == ROBOT_NODE_LASER_UP && now >= n->retry_at_us) {
        coslam_status_t st = COSLAM_OK;
        const int r = laser_connect_step(n, &st);
        if (r > 0) {
            n->state = ROBOT_NODE_DRIVE_UP;
            n->laser_up = 1;
            n->laser_alive_us = now;
        } else if (r < 0) {
            n->ctr.laser_connect_failures++;
            n->retry_at_us = now + n->cfg.retry_period_us;
            result = st;
        }
    } else if (n->state != ROBOT_NODE_LASER_UP && n->cfg.laser_lost_us > 0U) {
        /* a laser that went silent after start-up (unplugged, or its line
         * garbled for longer than laser_lost_us) is counted lost and
         * reconnected every retry_period_us, as in laser_optional; until
         * then there is no scan, so no translation */
        result = laser_background(n);
    }
    if (n->state != ROBOT_NODE_LASER_UP) {
        hal_can_status_t cs;
        if (hal_can_get_status(n->io.can, &cs) == HAL_OK) {
            n->ctr.can_errors = cs.rx_overflow_count + cs.rx_malformed_count;
        }
        const coslam_status_t st = run_drive(n);
        if (result == COSLAM_OK) {
            result = st;
        }
        take_odometry(n);
        if (now - n->last_predict_us >= n->cfg.filter_period_us) {
            flush_prediction(n);
        }
        if (n->laser_up) {
            read_laser(n);
        }
    }
    read_sightings(n);
    if (n->meeting.send_waiting) {
        (void)meeting_send_due(&n->meeting, &n->filter, n->io.link, now);
    }
    if (meeting_poll_link(&n->meeting, n->io.link) > 0 || n->meeting.have_pending) {
        flush_prediction(n);
        (void)meeting_poll(&n->meeting, &n->filter, now, n->odo_pose, n->travel_m);
    } else if (n->meeting.merge_waiting) {
        /* only the outcome of a merge whose check waited for idle time */
        (void)meeting_poll(&n->meeting, &n->filter, now, n->odo_pose, n->travel_m);
    }

    n->cmd.vx_mps = 0.0;
    n->cmd.vy_mps = 0.0;
    n->cmd.w_radps = 0.0;
    if (n->state == ROBOT_NODE_RUN) {
        behaviour_input_t in;
        memset(&in, 0, sizeof in);
        in.now_us = now;
        in.odo_pose = n->odo_pose;
        cov3_t cov;
        slam_filter_pose(&n->filter, &in.map_pose, &cov);
        in.scan_ok = n->scan_n > 0U && now - n->scan_us <= n->cfg.scan_max_age_us;
        in.scan.params = &n->cfg.obstacle;
        in.scan.laser_in_robot = n->cfg.laser_in_robot;
        in.scan.range_m = n->scan_range_m;
        in.scan.angle_rad = n->scan_angle_rad;
        in.scan.n = n->scan_n;
        in.scan.stamp_us = n->scan_us;
        in.scan.heading_rad = n->scan_odo_pose.theta;
        in.scan.points_m = n->scan_points_m;
        in.scan.n_points = n->scan_n_points;
        in.bumped = bumped;
        in.peer_in_view = peer_in_view(n, &in.peer_bearing_rad);
        in.merged_all = meeting_merged_all(&n->meeting);
        /* done with the peers only once they hold our map and have been
         * told we hold theirs (meeting_owes_ack) */
        in.acked_all = meeting_acked_all(&n->meeting) && !meeting_owes_ack(&n->meeting);
        (void)behaviour_step(&n->behaviour, &in, &n->cmd);
        if (n->cfg.laser_optional && !in.scan_ok) {
            /* no obstacle behaviour without a scan: turn on the spot only */
            n->ctr.blind_steps++;
            n->cmd.vx_mps = 0.0;
            n->cmd.vy_mps = 0.0;
            n->cmd.w_radps = fmax(-n->cfg.blind_max_turn_radps, fmin(n->cfg.blind_max_turn_radps, n->cmd.w_radps));
        }
        const int held = n->hold || (!robot_node_gpio_attached(n) && !n->cfg.motion_without_gpio);
        if (held) {
            n->ctr.hold_steps++;
        }
        if (stop || held) {
            n->cmd.vx_mps = 0.0;
            n->cmd.vy_mps = 0.0;
            n->cmd.w_radps = 0.0;
        }
        const coslam_status_t st =
            cia402_omni_set_body_velocity(&n->drive, n->cmd.vx_mps, n->cmd.vy_mps, n->cmd.w_radps);
        if (st != COSLAM_OK) {
            n->ctr.drive_errors++;
        }
    }
    set_led(n, stop);
    return result;
}

coslam_status_t robot_node_shutdown(robot_node_t *n)
{
    if (n == NULL) {
        return COSLAM_E_ARG;
    }
    uint64_t now = n->now_us;
    (void)hal_clock_now_us(n->io.clock, &now);
    n->now_us = now;
    n->hold = 1;
    n->cmd.vx_mps = 0.0;
    n->cmd.vy_mps = 0.0;
    n->cmd.w_radps = 0.0;
    coslam_status_t result = COSLAM_OK;
    if (n->drive_started) {
        take_odometry(n);
        (void)cia402_omni_set_body_velocity(&n->drive, 0.0, 0.0, 0.0);
        (void)cia402_omni_enable(&n->drive, 0);
        result = cia402_omni_poll(&n->drive, now);
    }
    if (n->state != ROBOT_NODE_SHUTDOWN) {
        flush_prediction(n);
        /* streaming, or a connect under way (its MD may be about to start
         * the scans): QT, which ends either (and gives up the command) */
        if (urg_scip2_is_streaming(&n->urg) || urg_scip2_pending(&n->urg)) {
            (void)urg_scip2_laser_off(&n->urg);
        }
        n->laser_up = 0;
        robot_node_gpio_detach(n);
        n->state = ROBOT_NODE_SHUTDOWN;
    }
    return result;
}

coslam_status_t robot_node_release_drives(robot_node_t *n)
{
    if (n == NULL) {
        return COSLAM_E_ARG;
    }
    return n->drive_started ? cia402_omni_release(&n->drive) : COSLAM_OK;
}

robot_node_state_t robot_node_state(const robot_node_t *n)
{
    return n->state;
}

void robot_node_pose(const robot_node_t *n, pose2_t *pose, cov3_t *cov)
{
    slam_filter_pose(&n->filter, pose, cov);
}

void robot_node_odometry(const robot_node_t *n, pose2_t *pose, double *travel_m)
{
    if (pose != NULL) {
        *pose = n->odo_pose;
    }
    if (travel_m != NULL) {
        *travel_m = n->travel_m;
    }
}

coslam_status_t robot_node_export(robot_node_t *n, map_estimate_t *out)
{
    if (n == NULL || out == NULL) {
        return COSLAM_E_ARG;
    }
    return slam_filter_export(&n->filter, out);
}

coslam_status_t robot_node_export_observe(robot_node_t *n, map_estimate_t *out)
{
    if (n == NULL || out == NULL) {
        return COSLAM_E_ARG;
    }
    return slam_filter_export_observe(&n->filter, out, n->meeting.cfg.merge.step_units);
}

int robot_node_export_poll(robot_node_t *n, const map_estimate_t *out, coslam_status_t *st)
{
    return n == NULL ? -1 : slam_filter_export_poll(&n->filter, out, st);
}

coslam_status_t robot_node_take_event(robot_node_t *n, meeting_event_t *ev)
{
    if (n == NULL) {
        return COSLAM_E_ARG;
    }
    return meeting_take_event(&n->meeting, ev);
}

const occ_grid_t *robot_node_grid(const robot_node_t *n)
{
    return &n->grid;
}

behaviour_mode_t robot_node_mode(const robot_node_t *n)
{
    return n->behaviour.mode;
}

int robot_node_diverged(const robot_node_t *n)
{
    return n->health.diverged;
}

const health_t *robot_node_health(const robot_node_t *n)
{
    return &n->health;
}

const robot_node_counters_t *robot_node_counters(const robot_node_t *n)
{
    return &n->ctr;
}

const meeting_counters_t *robot_node_meeting_counters(const robot_node_t *n)
{
    return &n->meeting.ctr;
}

const urg_scip2_stats_t *robot_node_laser_stats(const robot_node_t *n)
{
    return urg_scip2_stats(&n->urg);
}

uint64_t robot_node_laser_rx_search_bytes(const robot_node_t *n)
{
    /* what the driver counted since the last step's addition, too */
    return n->laser_rx_search_bytes + (uint32_t)(urg_scip2_rx_search_bytes(&n->urg) - n->laser_rx_search_seen);
}
