/* coslam-robot's camera: V4L2 + the marker detector (robot_camera.h). */
#include "robot_camera.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "vision/marker_spec.h"

__attribute__((format(printf, 3, 4))) static void put_text(char *dst, size_t cap, const char *fmt, ...)
{
    if (dst == NULL || cap == 0U) {
        return;
    }
    va_list ap;
    va_start(ap, fmt);
    (void)vsnprintf(dst, cap, fmt, ap);
    va_end(ap);
}

int robot_camera_say_limits(const robot_camera_t *c, uint64_t *seen, unsigned robot_id, FILE *out)
{
    const robot_camera_counters_t cc = robot_camera_counters(c);
    if (cc.detect_partial <= *seen) {
        return 0;
    }
    *seen = cc.detect_partial;
    fprintf(out,
            "coslam-robot: LIMIT robot %u: %llu camera frames detected only in part: the marker detector's "
            "capacity was reached and markers in the rest of the frame were lost (cam_detect_partial; "
            "VISION_MAX_RUNS = %d, VISION_MAX_BLOBS = %d, VISION_MAX_PAIR_CANDIDATES = %d in this build, "
            "vision/vision_config.h; a cluttered or noisy view)\n",
            robot_id, (unsigned long long)cc.detect_partial, (int)VISION_MAX_RUNS, (int)VISION_MAX_BLOBS,
            (int)VISION_MAX_PAIR_CANDIDATES);
    return 1;
}

static hal_status_t rc_next_frame(sighting_source_t *s, sighting_frame_t *out, uint32_t timeout_us);
static const sighting_source_ops_t rc_ops = {rc_next_frame};

void robot_camera_init(robot_camera_t *c, const robot_config_t *cfg, hal_clock_t *clock)
{
    memset(c, 0, sizeof *c);
    c->src.ops = &rc_ops;
    c->src.backend = c;
    c->cfg = cfg;
    c->clock = clock;
    c->v4l2.fd = -1;
}

/* The backend's few log lines, named like every device report. */
static void v4l2_log(void *ctx, const char *line)
{
    const robot_camera_t *c = (const robot_camera_t *)ctx;
    fprintf(stderr, "coslam-robot: camera (%s): %s\n", c->cfg->camera_device, line);
    fflush(stderr);
}

static hal_status_t from_vision(vision_status_t v)
{
    switch (v) {
    case VISION_OK: return HAL_OK;
    case VISION_E_IO: return HAL_E_NOT_FOUND;
    case VISION_E_FORMAT:
    case VISION_E_CRC: return HAL_E_CORRUPT;
    case VISION_E_ARG: return HAL_E_ARG;
    default: return HAL_E_IO;
    }
}

/* Colour table, range model, detector and frame buffer: once per process
 * (the first open that gets this far; on the opener thread, which owns
 * det, buf and cap while the camera is closed). */
static hal_status_t make_detector(robot_camera_t *c, char *msg, size_t msg_cap)
{
    const robot_config_t *cfg = c->cfg;
    static vision_lut_t lut; /* 32 KB, needed only here: the detector copies it */
    vision_status_t vst = vision_lut_load(&lut, cfg->camera_colour_table);
    if (vst != VISION_OK) {
        put_text(msg, msg_cap, "colour table %s: %s (%s)", cfg->camera_colour_table,
                 vst == VISION_E_IO ? strerror(errno) : "not a colour table", vision_status_name(vst));
        return from_vision(vst);
    }
    vision_range_model_t model = vision_range_model_pinhole();
    if (cfg->camera_range_model[0] != '\0') {
        vst = vision_range_model_load(&model, cfg->camera_range_model);
        if (vst != VISION_OK) {
            put_text(msg, msg_cap, "range model %s: %s (%s)", cfg->camera_range_model,
                     vst == VISION_E_IO ? strerror(errno) : "not a range model", vision_status_name(vst));
            return from_vision(vst);
        }
    }
    vision_config_t vc = vision_config_default();
    /* the default intrinsics are for 320 px; the same lens at another
     * width: focal length in proportion, principal point at the centre */
    vc.focal_px = vc.focal_px * (double)cfg->camera_width_px / (double)VISION_IMAGE_WIDTH_PX;
    vc.width_px = cfg->camera_width_px;
    vc.height_px = cfg->camera_height_px;
    vc.cx_px = 0.5 * (double)(cfg->camera_width_px - 1U);
    vc.cy_px = 0.5 * (double)(cfg->camera_height_px - 1U);
    const size_t cap = (size_t)cfg->camera_width_px * cfg->camera_height_px * 3U;
    uint8_t *buf = (uint8_t *)malloc(cap);
    if (buf == NULL) {
        put_text(msg, msg_cap, "no memory for a %zu byte frame buffer", cap);
        return HAL_E_IO;
    }
    vst = vision_detector_create(&c->det, &vc, &lut, &model);
    if (vst != VISION_OK) {
        free(buf);
        c->det = NULL;
        put_text(msg, msg_cap, "marker detector: %s", vision_status_name(vst));
        return from_vision(vst);
    }
    c->buf = buf;
    c->cap = cap;
    return HAL_OK;
}

hal_status_t robot_camera_open_prepare(robot_camera_t *c, char *msg, size_t msg_cap)
{
    put_text(msg, msg_cap, "%s", "");
    if (c == NULL || c->cfg == NULL) {
        return HAL_E_ARG;
    }
    robot_camera_close(c);
    c->opened = NULL;
    c->open_bad_format = 0;
    return HAL_OK;
}

hal_status_t robot_camera_open_device(robot_camera_t *c, char *msg, size_t msg_cap)
{
    const robot_config_t *cfg = c->cfg;
    if (c->det == NULL) {
        const hal_status_t st = make_detector(c, msg, msg_cap);
        if (st != HAL_OK) {
            return st;
        }
    }
    hal_camera_v4l2_config_t vc;
    memset(&vc, 0, sizeof vc);
    vc.device = cfg->camera_device;
    vc.width_px = cfg->camera_width_px;
    vc.height_px = cfg->camera_height_px;
    vc.inputs[0] = cfg->camera_mjpeg_first ? HAL_CAMERA_V4L2_IN_MJPEG : HAL_CAMERA_V4L2_IN_YUYV;
    vc.inputs[1] = cfg->camera_mjpeg_first ? HAL_CAMERA_V4L2_IN_YUYV : HAL_CAMERA_V4L2_IN_MJPEG;
    vc.output = HAL_CAMERA_PIX_RGB24;
    /* a lost camera is closed and reopened by the device slot every
     * retry period; the backend's own reopen would say the same period */
    vc.reopen_period_us = (uint32_t)(cfg->retry_period_s * 1e6);
    vc.log = v4l2_log;
    vc.log_ctx = c;
    hal_camera_t *cam = hal_camera_v4l2_open(&vc, &c->v4l2);
    if (cam == NULL) {
        const hal_status_t st = c->v4l2.open_status;
        put_text(msg, msg_cap, "V4L2 open: %s", hal_status_str(st));
        return st;
    }
    hal_camera_format_t fmt;
    hal_status_t st = hal_camera_get_format(cam, &fmt);
    if (st == HAL_OK && (fmt.width_px != cfg->camera_width_px || fmt.height_px != cfg->camera_height_px)) {
        c->open_bad_format = 1;
        put_text(msg, msg_cap, "the camera gives %ux%u, configured %ux%u ([camera] width_px, height_px)",
                 (unsigned)fmt.width_px, (unsigned)fmt.height_px, (unsigned)cfg->camera_width_px,
                 (unsigned)cfg->camera_height_px);
        st = HAL_E_ARG;
    }
    if (st == HAL_OK) {
        st = vision_source_init(&c->vs, cam, c->det, c->buf, c->cap);
        if (st != HAL_OK) {
            put_text(msg, msg_cap, "start streaming: %s", hal_status_str(st));
        }
    }
    if (st != HAL_OK) {
        (void)hal_camera_stop(cam);
        hal_camera_close(cam);
        return st;
    }
    c->opened = cam;
    return HAL_OK;
}

hal_status_t robot_camera_open_finish(robot_camera_t *c, hal_status_t st)
{
    if (c->open_bad_format) {
        c->ctr.bad_format++;
        c->open_bad_format = 0;
    }
    if (st != HAL_OK || c->opened == NULL) {
        c->ctr.open_failures++;
        c->opened = NULL;
        return st != HAL_OK ? st : HAL_E_IO;
    }
    c->camera = c->opened;
    c->opened = NULL;
    (void)hal_clock_now_us(c->clock, &c->last_frame_us);
    c->ctr.opens++;
    return HAL_OK;
}

/* The open session's source counters into the totals (at close). */
static void fold(robot_camera_counters_t *t, const vision_source_counters_t *s)
{
    t->frames += s->frames;
    t->landmarks += s->landmarks;
    t->robots += s->robots;
    t->detect_partial += s->detect_partial;
    t->foreign_robots += s->foreign_robots;
}

void robot_camera_close(robot_camera_t *c)
{
    if (c == NULL || c->camera == NULL) {
        return;
    }
    fold(&c->ctr, &c->vs.ctr);
    memset(&c->vs.ctr, 0, sizeof c->vs.ctr);
    (void)hal_camera_stop(c->camera);
    hal_camera_close(c->camera);
    c->camera = NULL;
}

void robot_camera_free(robot_camera_t *c)
{
    if (c == NULL) {
        return;
    }
    robot_camera_close(c);
    vision_detector_destroy(c->det);
    c->det = NULL;
    free(c->buf);
    c->buf = NULL;
    c->cap = 0U;
}

robot_camera_counters_t robot_camera_counters(const robot_camera_t *c)
{
    robot_camera_counters_t t = c->ctr;
    if (c->camera != NULL) {
        fold(&t, &c->vs.ctr);
    }
    return t;
}

static hal_status_t rc_next_frame(sighting_source_t *s, sighting_frame_t *out, uint32_t timeout_us)
{
    robot_camera_t *c = (robot_camera_t *)s->backend;
    if (c->camera == NULL) {
        return HAL_E_CLOSED;
    }
    const hal_status_t st = sighting_source_next_frame(vision_source_handle(&c->vs), out, timeout_us);
    uint64_t now = c->last_frame_us;
    (void)hal_clock_now_us(c->clock, &now);
    if (st == HAL_OK) {
        c->last_frame_us = now;
        return HAL_OK;
    }
    if (st != HAL_E_TIMEOUT) {
        c->ctr.errors++;
    }
    if (!hal_camera_v4l2_connected(&c->v4l2)) {
        /* gone (unplugged, driver error): the slot closes it and reopens it */
        c->ctr.disconnects++;
        return HAL_E_CLOSED;
    }
    if (st == HAL_E_TIMEOUT && c->cfg->camera_stall_us > 0U && now - c->last_frame_us >= c->cfg->camera_stall_us) {
        c->ctr.stalls++;
        c->last_frame_us = now; /* one stall per silence, also if the caller keeps calling */
        return HAL_E_CLOSED;
    }
    return st;
}
