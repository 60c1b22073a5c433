#include "app/behaviour.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

behaviour_config_t behaviour_config_default(void)
{
    behaviour_config_t c;
    c.cruise_mps = 0.2;
    c.turn_gain = 1.5;
    c.max_turn_radps = 0.8;
    c.heading_tol_rad = 5.0 * COSLAM_PI / 180.0;
    c.straight_band_rad = 30.0 * COSLAM_PI / 180.0;
    c.probe_max_rad = 60.0 * COSLAM_PI / 180.0;
    c.probe_step_rad = 10.0 * COSLAM_PI / 180.0;
    c.probe_margin_m = 0.1;
    c.slide_mps = 0.05;
    c.guard_horizon_s = 0.3;
    c.guard_patience_s = 1.0;
    c.explore_s = 90.0;
    c.rendezvous_m.x = 0.0;
    c.rendezvous_m.y = 0.0;
    c.goal_tol_m = 0.25;
    c.bypass_s = 1.0;
    c.seek_turn_radps = 0.4;
    c.face_gain = 1.5;
    c.peer_timeout_s = 1.0;
    c.linger_s = 10.0;
    return c;
}

static int pos_finite(double v)
{
    return isfinite(v) && v > 0.0;
}

coslam_status_t behaviour_init(behaviour_t *b, const behaviour_config_t *cfg)
{
    if (b == NULL || cfg == NULL) {
        return COSLAM_E_ARG;
    }
    if (!pos_finite(cfg->cruise_mps) || !pos_finite(cfg->turn_gain) || !pos_finite(cfg->max_turn_radps) ||
        !pos_finite(cfg->heading_tol_rad) || !pos_finite(cfg->straight_band_rad) || !pos_finite(cfg->probe_max_rad) ||
        !pos_finite(cfg->probe_step_rad) || !(isfinite(cfg->probe_margin_m) && cfg->probe_margin_m >= 0.0) ||
        !(isfinite(cfg->slide_mps) && cfg->slide_mps >= 0.0) || !pos_finite(cfg->guard_horizon_s) ||
        !pos_finite(cfg->guard_patience_s) ||
        !isfinite(cfg->explore_s) || !isfinite(cfg->rendezvous_m.x) || !isfinite(cfg->rendezvous_m.y) ||
        !pos_finite(cfg->goal_tol_m) || !(isfinite(cfg->bypass_s) && cfg->bypass_s >= 0.0) ||
        !isfinite(cfg->seek_turn_radps) || cfg->seek_turn_radps == 0.0 || !pos_finite(cfg->face_gain) ||
        !pos_finite(cfg->peer_timeout_s) || !(isfinite(cfg->linger_s) && cfg->linger_s >= 0.0)) {
        return COSLAM_E_ARG;
    }
    memset(b, 0, sizeof *b);
    b->cfg = *cfg;
    b->mode = cfg->explore_s == 0.0 ? BEHAVIOUR_RETURN : BEHAVIOUR_WANDER;
    b->ahead_scan_us = UINT64_MAX; /* no scan used yet (0 is a valid stamp) */
    b->planned_scan_us = UINT64_MAX;
    return COSLAM_OK;
}

static double clampd(double v, double lim)
{
    return v > lim ? lim : (v < -lim ? -lim : v);
}

static uint64_t after_s(uint64_t now_us, double s)
{
    return now_us + (uint64_t)(s * 1e6);
}

/* Translation allowed at heading error e: 1 straight, 0 beyond the band. */
static double straight_factor(const behaviour_t *b, double e)
{
    return fmax(0.0, 1.0 - fabs(e) / b->cfg.straight_band_rad);
}

/* Turn towards the held heading; translate at `speed` scaled by the band rule. */
static void steer(const behaviour_t *b, double heading_now, double speed, behaviour_cmd_t *out)
{
    const double e = angle_wrap(b->hold_heading_rad - heading_now);
    out->w_radps = clampd(b->cfg.turn_gain * e, b->cfg.max_turn_radps);
    out->vx_mps = speed * straight_factor(b, e);
}

/* The obstacle behaviour along direction dir_rad (robot frame), its corridor
 * widened by extra_margin_m each side; 1 if an obstacle is in that corridor
 * (a degenerate one counts). */
static int probe(const behaviour_input_t *in, double dir_rad, double extra_margin_m, obstacle_cmd_t *cmd)
{
    memset(cmd, 0, sizeof *cmd);
    cmd->nearest_m = INFINITY;
    if (!in->scan_ok || in->scan.n == 0U || in->scan.params == NULL) {
        return 0;
    }
    obstacle_params_t p = *in->scan.params;
    p.margin_m += extra_margin_m;
    const coslam_status_t st =
        obstacle_evaluate(&p, in->scan.laser_in_robot, dir_rad, in->scan.range_m, in->scan.angle_rad, in->scan.n, cmd);
    return (st == COSLAM_OK || st == COSLAM_E_DEGENERATE) && cmd->detected;
}

/* Bumper turns and the obstacle behaviour ahead: start or continue a right
 * turn. The obstacle behaviour runs once per scan, along the heading the
 * robot had when the scan was taken; the turn target is that heading plus
 * dpsi. Returns 1 if it commands this step. */
static int avoid(behaviour_t *b, const behaviour_input_t *in, behaviour_cmd_t *out)
{
    if (in->bumped) {
        b->bump_turns++;
        b->turning = 1;
        b->ahead_hit = 0;
        b->hold_heading_rad = angle_wrap(in->odo_pose.theta - 0.5 * COSLAM_PI);
    } else if (in->scan_ok && in->scan.stamp_us != b->ahead_scan_us) {
        b->ahead_scan_us = in->scan.stamp_us;
        b->ahead_hit = probe(in, 0.0, 0.0, &b->ahead);
        /* A line within heading_tol of the motion is parallel whichever way
         * it leans: one receding to the left by a hair gets dpsi near -pi
         * from the right-turn rule (coslam/obstacle.h step 5), and a robot
         * running along a wall would turn round on scan noise. */
        if (b->ahead_hit && b->ahead.heading_change_rad < -COSLAM_PI + b->cfg.heading_tol_rad) {
            b->ahead.heading_change_rad = 0.0;
            b->ahead.speed_mps = b->ahead.nearest_m < in->scan.params->min_clearance_m ? 0.0 : b->cfg.cruise_mps;
            b->near_parallel++;
        }
        if (b->ahead_hit) {
            if (!b->turning) {
                b->avoid_turns++;
            }
            b->turning = 1;
            b->hold_heading_rad = angle_wrap(in->scan.heading_rad + b->ahead.heading_change_rad);
            b->straight_until_us = after_s(in->now_us, b->cfg.bypass_s);
        }
    }
    if (!in->scan_ok) {
        b->ahead_hit = 0;
    }
    const double e = angle_wrap(b->hold_heading_rad - in->odo_pose.theta);
    if (b->ahead_hit) {
        /* turn on the spot until parallel, then the behaviour's speed (known
         * from the scan that saw the robot parallel): translating during the
         * turn keeps a round obstacle in the corridor, and the robot would
         * orbit it */
        out->w_radps = clampd(b->cfg.turn_gain * e, b->cfg.max_turn_radps);
        const int parallel = fabs(b->ahead.heading_change_rad) < b->cfg.heading_tol_rad;
        out->vx_mps = fabs(e) < b->cfg.heading_tol_rad && parallel ? b->ahead.speed_mps : 0.0;
        /* along a parallel obstacle that is inside the corridor, slide away
         * sideways (the base is omnidirectional): turning away would make it
         * a receding line, and the right-turn rule would then ask for a
         * half turn */
        const double half = 0.5 * in->scan.params->robot_width_m + in->scan.params->margin_m;
        if (parallel && b->ahead.line_ok && b->ahead.line.dist_m < half) {
            out->vy_mps = b->ahead.line.centroid.y >= 0.0 ? -b->cfg.slide_mps : b->cfg.slide_mps;
            b->slides++;
        }
        return 1;
    }
    if (b->turning) {
        if (fabs(e) < b->cfg.heading_tol_rad) {
            b->turning = 0;
            b->straight_until_us = after_s(in->now_us, b->cfg.bypass_s);
            return 0;
        }
        steer(b, in->odo_pose.theta, b->cfg.cruise_mps, out);
        return 1;
    }
    return 0;
}

/* The last safety net, below the behaviours: would the commanded translation
 * bring the body (half the robot's width) within reach of a scan point in
 * the next guard_horizon_s? Only points it approaches count, so a robot
 * beside a wall may still move along or away from it. O(scan points). */
static int guard_blocks(const behaviour_t *b, const behaviour_input_t *in, const behaviour_cmd_t *cmd)
{
    const double reach = 0.5 * in->scan.params->robot_width_m;
    const double t = b->cfg.guard_horizon_s;
    /* the points are in the robot frame of the scan; the robot may have
     * turned since: rotate the displacement into that frame instead */
    const double dth = angle_wrap(in->odo_pose.theta - in->scan.heading_rad);
    const double c = cos(dth);
    const double s = sin(dth);
    const double px = (c * cmd->vx_mps - s * cmd->vy_mps) * t;
    const double py = (s * cmd->vx_mps + c * cmd->vy_mps) * t;
    for (size_t i = 0; i < in->scan.n_points; ++i) {
        const point2_t q = in->scan.points_m[i];
        const double d_then2 = (q.x - px) * (q.x - px) + (q.y - py) * (q.y - py);
        if (d_then2 < reach * reach && d_then2 < q.x * q.x + q.y * q.y) {
            return 1;
        }
    }
    return 0;
}

/* RETURN: hold the clear direction closest to the goal bearing eg. */
static void plan_return(behaviour_t *b, const behaviour_input_t *in, double eg)
{
    const int n_dir = (int)floor(b->cfg.probe_max_rad / b->cfg.probe_step_rad);
    double best = 0.0;
    double best_cost = INFINITY;
    for (int i = -n_dir; i <= n_dir; ++i) {
        const double d = (double)i * b->cfg.probe_step_rad;
        const double cost = fabs(angle_wrap(eg - d));
        obstacle_cmd_t c;
        if (cost < best_cost && !probe(in, d, b->cfg.probe_margin_m, &c)) {
            best_cost = cost;
            best = d;
        }
    }
    if (!isfinite(best_cost)) {
        b->goal_blocked++;
        best = -0.5 * COSLAM_PI; /* boxed in: turn right and look again */
    } else if (fabs(angle_wrap(eg - best)) > 0.5 * b->cfg.probe_step_rad && fabs(eg) <= b->cfg.probe_max_rad) {
        b->goal_blocked++;
    }
    b->hold_heading_rad = angle_wrap(in->scan.heading_rad + best);
}

static void set_mode(behaviour_t *b, behaviour_mode_t m)
{
    if (b->mode != m) {
        b->mode = m;
        b->mode_changes++;
        b->turning = 0;
    }
}

behaviour_mode_t behaviour_step(behaviour_t *b, const behaviour_input_t *in, behaviour_cmd_t *out)
{
    out->vx_mps = 0.0;
    out->vy_mps = 0.0;
    out->w_radps = 0.0;
    if (!b->started) {
        b->started = 1;
        b->start_us = in->now_us;
        b->hold_heading_rad = in->odo_pose.theta;
    }
    const double t_s = (double)(in->now_us - b->start_us) * 1e-6;
    const point2_t goal = pose2_apply_inverse(in->map_pose, b->cfg.rendezvous_m);
    const double goal_dist = hypot(goal.x, goal.y);

    /* transitions */
    if (in->merged_all && !b->merged_seen) {
        b->merged_seen = 1;
        b->merged_since_us = in->now_us;
    }
    const int done = in->merged_all &&
                     (in->acked_all || (double)(in->now_us - b->merged_since_us) * 1e-6 >= b->cfg.linger_s);
    if (done && b->mode != BEHAVIOUR_WANDER) {
        b->rendezvous_done = 1;
        set_mode(b, BEHAVIOUR_WANDER);
        b->hold_heading_rad = in->odo_pose.theta;
    }
    switch (b->mode) {
    case BEHAVIOUR_WANDER:
        if (b->cfg.explore_s >= 0.0 && t_s >= b->cfg.explore_s && !done && !b->rendezvous_done) {
            set_mode(b, BEHAVIOUR_RETURN);
        }
        break;
    case BEHAVIOUR_RETURN:
        if (goal_dist < b->cfg.goal_tol_m) {
            set_mode(b, BEHAVIOUR_SEEK);
        }
        break;
    case BEHAVIOUR_SEEK:
        if (in->peer_in_view) {
            set_mode(b, BEHAVIOUR_FACE);
        }
        break;
    case BEHAVIOUR_FACE:
        if (!in->peer_in_view) {
            set_mode(b, BEHAVIOUR_SEEK);
        }
        break;
    }

    /* command */
    switch (b->mode) {
    case BEHAVIOUR_WANDER:
        if (!avoid(b, in, out)) {
            steer(b, in->odo_pose.theta, b->cfg.cruise_mps, out);
        }
        break;
    case BEHAVIOUR_RETURN:
        if (!avoid(b, in, out)) {
            if (in->now_us >= b->straight_until_us && in->scan_ok && in->scan.stamp_us != b->planned_scan_us) {
                b->planned_scan_us = in->scan.stamp_us;
                plan_return(b, in, atan2(goal.y, goal.x));
            }
            steer(b, in->odo_pose.theta, b->cfg.cruise_mps * fmin(1.0, goal_dist / 0.5), out);
        }
        break;
    case BEHAVIOUR_SEEK:
        out->w_radps = clampd(b->cfg.seek_turn_radps, b->cfg.max_turn_radps);
        break;
    case BEHAVIOUR_FACE:
        if (in->peer_in_view) {
            out->w_radps = clampd(b->cfg.face_gain * in->peer_bearing_rad, b->cfg.max_turn_radps);
        }
        break;
    }
    if (!in->scan_ok) {
        out->vx_mps = 0.0; /* blind: turn at most */
        out->vy_mps = 0.0;
    } else if ((out->vx_mps != 0.0 || out->vy_mps != 0.0) && guard_blocks(b, in, out)) {
        out->vx_mps = 0.0;
        out->vy_mps = 0.0;
        b->guard_stops++;
        if (!b->guard_held) {
            b->guard_held = 1;
            b->guard_since_us = in->now_us;
        } else if ((double)(in->now_us - b->guard_since_us) * 1e-6 >= b->cfg.guard_patience_s) {
            /* held back too long: turn away as after a bump */
            b->guard_held = 0;
            b->bump_turns++;
            b->turning = 1;
            b->ahead_hit = 0;
            b->hold_heading_rad = angle_wrap(in->odo_pose.theta - 0.5 * COSLAM_PI);
        }
    } else {
        b->guard_held = 0;
    }
    return b->mode;
}

const char *behaviour_mode_name(behaviour_mode_t mode)
{
    switch (mode) {
    case BEHAVIOUR_WANDER: return "wander";
    case BEHAVIOUR_RETURN: return "return";
    case BEHAVIOUR_SEEK: return "seek";
    case BEHAVIOUR_FACE: return "face";
    }
    return "?";
}
