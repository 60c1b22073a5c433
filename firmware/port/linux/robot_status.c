/* Status report of coslam-robot (robot_status.h). */
#include "robot_status.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>

static robot_status_kv_t *slot(robot_status_t *s, const char *key, int is_text)
{
    if (s->n >= ROBOT_STATUS_MAX_KV - 1) { /* the last slot: status_dropped */
        s->dropped++;
        return NULL;
    }
    robot_status_kv_t *kv = &s->kv[s->n++];
    kv->key = key;
    kv->is_text = is_text;
    kv->value[0] = '\0';
    return kv;
}

static void text(robot_status_t *s, const char *key, const char *v)
{
    robot_status_kv_t *kv = slot(s, key, 1);
    if (kv != NULL) {
        (void)snprintf(kv->value, sizeof kv->value, "%s", v);
    }
}

static void u64(robot_status_t *s, const char *key, uint64_t v)
{
    robot_status_kv_t *kv = slot(s, key, 0);
    if (kv != NULL) {
        (void)snprintf(kv->value, sizeof kv->value, "%llu", (unsigned long long)v);
    }
}

static void f64(robot_status_t *s, const char *key, double v, int decimals)
{
    robot_status_kv_t *kv = slot(s, key, 0);
    if (kv != NULL) {
        (void)snprintf(kv->value, sizeof kv->value, "%.*f", decimals, v);
    }
}

static const char *state_name(robot_node_state_t st)
{
    switch (st) {
    case ROBOT_NODE_LASER_UP: return "laser_up";
    case ROBOT_NODE_DRIVE_UP: return "drive_up";
    case ROBOT_NODE_RUN: return "run";
    case ROBOT_NODE_FAULT: return "fault";
    case ROBOT_NODE_SHUTDOWN: return "shutdown";
    }
    return "?";
}

void robot_status_collect(robot_status_t *s, robot_node_t *node, const robot_devices_t *dev,
                          const robot_snapshots_t *snaps, const robot_loop_stats_t *loop)
{
    memset(s, 0, sizeof *s);
    f64(s, "t", loop->uptime_s, 1);
    u64(s, "id", node->cfg.robot_id);
    text(s, "state", state_name(robot_node_state(node)));
    text(s, "mode", behaviour_mode_name(robot_node_mode(node)));
    for (int i = 0; i < ROBOT_DEV_COUNT; ++i) {
        text(s, dev->dev[i].name, robot_dev_state_name(dev->dev[i].state));
    }
    u64(s, "steps", loop->steps);
    u64(s, "overruns", loop->overruns);
    u64(s, "late_max_us", loop->late_max_us);
    f64(s, "cpu_pct", loop->cpu_pct, 2);

    const robot_node_counters_t *c = robot_node_counters(node);
    u64(s, "node_steps", c->steps);
    u64(s, "scans", c->scans);
    u64(s, "scan_errors", c->scan_errors);
    u64(s, "laser_streaming", (uint64_t)robot_node_laser_up(node));
    u64(s, "laser_connect_failures", c->laser_connect_failures);
    u64(s, "laser_lost", c->laser_lost);
    u64(s, "grid_out_of_grid", c->grid_out_of_grid);
    u64(s, "frames", c->frames);
    u64(s, "views", c->views);
    u64(s, "frame_errors", c->frame_errors);
    u64(s, "sightings_dropped", c->sightings_dropped);
    u64(s, "robot_sightings_refused", c->robot_sightings_refused);
    u64(s, "filter_errors", c->filter_errors);
    u64(s, "odometry_errors", c->odometry_errors);
    u64(s, "drive_faults", c->drive_faults);
    u64(s, "drive_errors", c->drive_errors);
    /* the drive driver's own (cia402_omni_t, since the node's start: the
     * driver is initialised once): odometry restarted for a silent wheel,
     * commands scaled down, frames the HAL lost or no wheel claimed, master
     * heartbeats refused */
    const cia402_omni_t *dr = &node->drive;
    u64(s, "drive_odo_gaps", dr->odo_gaps);
    u64(s, "drive_saturations", dr->saturations);
    u64(s, "drive_rx_overflows", dr->rx_overflows);
    u64(s, "drive_rx_foreign", dr->rx_foreign);
    u64(s, "drive_hb_failures", dr->master_hb_failures);
    u64(s, "stalls", c->stalls);
    u64(s, "stall_resets", c->stall_resets);
    u64(s, "stop_steps", c->stop_steps);
    u64(s, "hold_steps", c->hold_steps);
    u64(s, "blind_steps", c->blind_steps);
    u64(s, "bumper_acks", c->bumper_acks);
    u64(s, "gpio_attach_failures", c->gpio_attach_failures);
    u64(s, "diverged", c->diverged);
    u64(s, "diverged_now", (uint64_t)robot_node_diverged(node));
    u64(s, "health_unjudged", node->health.unjudged_frames);
    u64(s, "can_errors", c->can_errors);
    u64(s, "can_stamps_unbelieved", robot_devices_can_stamps_unbelieved(dev)); /* since the start, across reopens */

    const meeting_counters_t *m = robot_node_meeting_counters(node);
    u64(s, "mt_sent", m->sent);
    u64(s, "mt_send_failures", m->send_failures);
    u64(s, "mt_received", m->received);
    u64(s, "mt_rx_errors", m->rx_errors);
    u64(s, "mt_not_for_me", m->not_for_me);
    u64(s, "mt_wrong_sender", m->wrong_sender);
    u64(s, "mt_ignored_recent", m->ignored_recent);
    u64(s, "mt_replays", m->replays);
    u64(s, "mt_stale", m->stale);
    u64(s, "mt_history_thinned", m->history_thinned);
    u64(s, "mt_merged", m->merged);
    u64(s, "mt_merge_failures", m->merge_failures);
    u64(s, "mt_refused_range", m->refused_range);
    u64(s, "mt_refused_disagree", m->refused_disagree);
    u64(s, "mt_refused_lost", m->refused_lost);
    u64(s, "mt_events_dropped", m->events_dropped);
    u64(s, "mt_pending_replaced", m->pending_replaced);
    u64(s, "mt_refused_implausible", m->refused_implausible);
    u64(s, "mt_ignored_disagreed", m->ignored_disagreed);
    u64(s, "mt_weak_not_sent", m->weak_not_sent);
    u64(s, "mt_send_waits", m->send_waits);
    u64(s, "mt_send_busy", m->send_busy);
    u64(s, "mt_rebased", node->meeting.session.rebased);
    /* the filter's loss counters (the LIMIT / warning lines' counters) */
    slam_filter_limit_t lim[SLAM_FILTER_N_LIMITS];
    const int n_lim = slam_filter_limits(&node->filter, lim);
    static const char *const loss_keys[] = {"lm_capacity_drops",   "sighting_capacity_drops", "export_capacity_drops",
                                            "rejected_controls",   "rejected_sightings",      "numeric_faults",
                                            "merge_pair_drops",    "tree_capacity_drops"};
    for (size_t k = 0; k < sizeof loss_keys / sizeof loss_keys[0]; ++k) {
        uint64_t v = 0;
        for (int i = 0; i < n_lim; ++i) {
            if (strcmp(lim[i].counter, loss_keys[k]) == 0) {
                v = lim[i].value;
            }
        }
        u64(s, loss_keys[k], v);
    }
    /* how often the filter finds its confirmed landmarks where it expects
     * them (slam_filter_view_counts): a camera or a map going wrong shows
     * as a falling view_pairs / (view_pairs + view_misses) */
    uint64_t view_pairs = 0;
    uint64_t view_misses = 0;
    slam_filter_view_counts(&node->filter, &view_pairs, &view_misses);
    u64(s, "view_pairs", view_pairs);
    u64(s, "view_misses", view_misses);
    /* EKF-SLAM's revisits kept as two hypotheses, and those decided for
     * the one without the revisit (ekfslam_config_t.mh_frames; 0 for
     * Fast-SLAM) */
    const int is_ekf = node->filter.kind == SLAM_FILTER_EKF;
    u64(s, "mh_forks", is_ekf ? node->filter.u.ekf.ctr.mh_forks : 0U);
    u64(s, "mh_reverted", is_ekf ? node->filter.u.ekf.ctr.mh_reverted : 0U);
    /* the compressed EKF's regions with more landmarks in reach than
     * COSLAM_EKF_MAX_ACTIVE: those frames ran the full update (slower,
     * not lossy; 0 where the profile has no compressed EKF) */
    u64(s, "cekf_active_overflows", is_ekf ? node->filter.u.ekf.ctr.cekf_active_overflows : 0U);
    /* work in parts (docs/scale.md): merges, sends and the observers' exports */
    const slam_filter_t *fl = &node->filter;
    u64(s, "idle_calls", loop->idle_calls);
    u64(s, "merges_in_parts", fl->merges_in_parts);
    u64(s, "merges_late_partial", fl->merges_late_partial);
    u64(s, "merges_forced", fl->merges_forced);
    u64(s, "inputs_held", fl->inputs_held);
    u64(s, "held_failures", fl->held_failures);
    u64(s, "holds_forced", fl->holds_forced);
    u64(s, "sends_in_parts", fl->sends_in_parts);
    u64(s, "sends_forced", fl->sends_forced);
    u64(s, "observes_in_parts", fl->observes_in_parts);
    u64(s, "observes_yielded", fl->observes_yielded);

    const urg_scip2_stats_t *u = robot_node_laser_stats(node);
    u64(s, "urg_scans_ok", u->scans_ok);
    u64(s, "urg_err_timeout", u->err_timeout);
    u64(s, "urg_err_io", u->err_io);
    u64(s, "urg_err_checksum", u->err_checksum);
    u64(s, "urg_err_line", u->err_line);
    u64(s, "urg_err_garbage", u->err_garbage);
    u64(s, "urg_resyncs", u->resyncs);
    u64(s, "urg_err_echo", u->err_echo);
    u64(s, "urg_err_status", u->err_status);
    u64(s, "urg_err_field", u->err_field);
    u64(s, "urg_err_capacity", u->err_capacity);
    u64(s, "urg_bytes_discarded", u->bytes_discarded);
    u64(s, "urg_messages_skipped", u->messages_skipped);
    u64(s, "urg_fields_truncated", u->fields_truncated);
    u64(s, "urg_stamp_backwards", u->stamp_backwards);
    u64(s, "urg_rx_search_bytes", robot_node_laser_rx_search_bytes(node)); /* since the start, across resets */

    pose2_t pose;
    cov3_t cov;
    robot_node_pose(node, &pose, &cov);
    u64(s, "landmarks", loop->landmarks);
    f64(s, "x", pose.x, 3);
    f64(s, "y", pose.y, 3);
    f64(s, "theta", pose.theta, 4);
    /* the link: its mode, the DDS counters and every authentication
     * refusal by its reason (a refused message is visible here) */
    const robot_link_t *l = &dev->link;
    robot_link_counters_t lc;
    robot_link_counters(l, &lc);
    text(s, "link_mode", robot_link_mode_name(l));
    u64(s, "dds_sent", lc.dds_sent);
    u64(s, "dds_send_not_map", lc.dds_send_not_map);
    u64(s, "dds_send_trailer_too_long", lc.dds_send_trailer_too_long);
    u64(s, "dds_send_busy", lc.dds_send_busy);
    u64(s, "dds_send_io", lc.dds_send_io);
    u64(s, "dds_delivered", lc.dds_delivered);
    u64(s, "dds_rx_overflow", lc.dds_rx_overflow);
    u64(s, "dds_rx_other_dest", lc.dds_rx_other_dest);
    u64(s, "dds_rx_own_id", lc.dds_rx_own_id);
    u64(s, "dds_rx_invalid", lc.dds_rx_invalid);
    u64(s, "dds_rx_not_data", lc.dds_rx_not_data);
    u64(s, "dds_lost", lc.dds_lost);
    u64(s, "dds_rejected", lc.dds_rejected);
    u64(s, "dds_rx_io", lc.dds_rx_io);
    uint64_t slow = 0U;
    uint64_t hung = 0U;
    uint64_t no_opener = 0U;
    uint64_t open_max = 0U;
    for (int i = 0; i < ROBOT_DEV_COUNT; ++i) {
        slow += dev->dev[i].slow_opens;
        hung += dev->dev[i].hung_opens;
        no_opener += dev->dev[i].opener_start_failures;
        open_max = dev->dev[i].open_max_ms > open_max ? dev->dev[i].open_max_ms : open_max;
    }
    u64(s, "dev_slow_opens", slow);
    u64(s, "dev_open_max_ms", open_max);
    u64(s, "dev_opening", robot_devices_opening(dev));
    u64(s, "dev_hung_opens", hung);
    u64(s, "dev_opener_failures", no_opener);
    u64(s, "link_opens", dev->dev[ROBOT_DEV_LINK].opens);
    u64(s, "link_open_failures", dev->dev[ROBOT_DEV_LINK].open_failures);
    u64(s, "link_losses", dev->dev[ROBOT_DEV_LINK].losses);
    u64(s, "auth_sent", lc.auth_sent);
    u64(s, "auth_send_not_map", lc.auth_send_not_map);
    u64(s, "auth_send_wrong_sender", lc.auth_send_wrong_sender);
    u64(s, "auth_send_too_long", lc.auth_send_too_long);
    u64(s, "auth_send_inner_failed", lc.auth_send_inner_failed);
    u64(s, "auth_delivered", lc.auth_delivered);
    u64(s, "auth_rx_overflow", lc.auth_rx_overflow);
    u64(s, "auth_refused", lc.auth_refused);
    u64(s, "auth_rx_malformed", lc.auth_rx_malformed);
    u64(s, "auth_rx_unauthenticated", lc.auth_rx_unauthenticated);
    u64(s, "auth_rx_truncated", lc.auth_rx_truncated);
    u64(s, "auth_rx_wrong_key", lc.auth_rx_wrong_key);
    u64(s, "auth_rx_bad_mac", lc.auth_rx_bad_mac);
    u64(s, "auth_rx_sender_mismatch", lc.auth_rx_sender_mismatch);
    u64(s, "auth_rx_stale", lc.auth_rx_stale);
    u64(s, "auth_rx_future", lc.auth_rx_future);
    u64(s, "auth_rx_replay", lc.auth_rx_replay);
    u64(s, "auth_rx_oversize", lc.auth_rx_oversize);

    u64(s, "snap_seq", snaps->newest_seq);
    u64(s, "snap_saves", snaps->saves);
    u64(s, "snap_failures", snaps->save_failures);
    u64(s, "snap_corrupt", snaps->corrupt_found);
    u64(s, "storage_fsync_failures", dev->storage_fsync_failures);
    u64(s, "storage_save_probes_failed", dev->storage_save_probes_failed);
    u64(s, "snap_writing_ms", loop->snap_writing_ms);
    u64(s, "snap_write_max_ms", (snaps->write_max_us + 999U) / 1000U);
    u64(s, "snap_busy_skips", snaps->busy_skips);
    u64(s, "snap_no_writer_skips", snaps->no_writer_skips);
    u64(s, "snap_writer_start_failures", snaps->writer_start_failures);
    u64(s, "snap_final_timeouts", snaps->final_timeouts);
    u64(s, "snap_start_read_timeouts", snaps->start_read_timeouts);
    u64(s, "status_file_failures", loop->status_file_failures);
    if (dev->camera_kind == ROBOT_SIGHTINGS_LIVE) {
        /* the e2e live stream (--sightings-fd): its refusals */
        uint32_t bad = 0U;
        uint32_t refused = 0U;
        robot_devices_live_counters(dev, &bad, &refused); /* since the start, across reopens */
        u64(s, "live_bad", bad);
        u64(s, "live_robots_refused", refused);
    }
#if COSLAM_HAVE_CAMERA
    /* the camera (robot_camera.h): only when one is configured */
    if (dev->camera_kind == ROBOT_SIGHTINGS_CAMERA) {
        const robot_camera_counters_t cc = robot_camera_counters(&dev->camera);
        u64(s, "cam_frames", cc.frames);
        u64(s, "cam_landmarks", cc.landmarks);
        u64(s, "cam_robots", cc.robots);
        u64(s, "cam_errors", cc.errors);
        u64(s, "cam_detect_partial", cc.detect_partial);
        u64(s, "cam_foreign_robots", cc.foreign_robots);
        u64(s, "cam_opens", cc.opens);
        u64(s, "cam_open_failures", cc.open_failures);
        u64(s, "cam_bad_format", cc.bad_format);
        u64(s, "cam_disconnects", cc.disconnects);
        u64(s, "cam_stalls", cc.stalls);
    }
#endif
    if (s->dropped > 0U) {
        /* a limit is said where it bites: the report itself ends with it */
        robot_status_kv_t *kv = &s->kv[s->n++];
        kv->key = "status_dropped";
        kv->is_text = 0;
        (void)snprintf(kv->value, sizeof kv->value, "%lu", (unsigned long)s->dropped);
    }
}

size_t robot_status_line(const robot_status_t *s, char *buf, size_t cap)
{
    size_t n = 0;
    if (cap == 0U) {
        return 0U;
    }
    buf[0] = '\0';
    for (int i = 0; i < s->n && n + 1U < cap; ++i) {
        const int w = snprintf(buf + n, cap - n, "%s%s=%s", i > 0 ? " " : "", s->kv[i].key, s->kv[i].value);
        if (w < 0) {
            break;
        }
        n += (size_t)w < cap - n ? (size_t)w : cap - n - 1U;
    }
    return n;
}

int robot_status_write_json(const robot_status_t *s, const char *path)
{
    char tmp[4096];
    if (snprintf(tmp, sizeof tmp, "%s.tmp", path) >= (int)sizeof tmp) {
        errno = ENAMETOOLONG;
        return -1;
    }
    errno = 0;
    FILE *f = fopen(tmp, "w");
    if (f == NULL) {
        return -1;
    }
    fprintf(f, "{");
    for (int i = 0; i < s->n; ++i) {
        /* keys and text values are plain identifiers and words: no escaping needed */
        fprintf(f, "%s\"%s\": %s%s%s", i > 0 ? ", " : "", s->kv[i].key, s->kv[i].is_text ? "\"" : "",
                s->kv[i].value, s->kv[i].is_text ? "\"" : "");
    }
    fprintf(f, "}\n");
    /* a write that failed before the last one (a full disk) leaves the
     * stream's error flag set, which fclose alone does not report */
    const int flushed = fflush(f) == 0 && !ferror(f);
    const int e_write = errno != 0 ? errno : EIO;
    if (fclose(f) != 0 || !flushed) {
        const int e = flushed ? errno : e_write;
        (void)remove(tmp);
        errno = e;
        return -1;
    }
    if (rename(tmp, path) != 0) {
        const int e = errno;
        (void)remove(tmp);
        errno = e;
        return -1;
    }
    return 0;
}
