/* The camera + detector sighting source (vision_source.h). */
#include "vision/vision_source.h"

#include <string.h>

static hal_status_t vs_next_frame(sighting_source_t *src, sighting_frame_t *out, uint32_t timeout_us);
static const sighting_source_ops_t vs_ops = {vs_next_frame};

static int format_usable(const vision_source_t *vs)
{
    const vision_config_t *cfg = vision_detector_config(vs->det);
    if (vs->fmt.width_px != cfg->width_px || vs->fmt.height_px != cfg->height_px) return 0;
    if (vs->fmt.pixfmt != HAL_CAMERA_PIX_RGB24 && vs->fmt.pixfmt != HAL_CAMERA_PIX_YUYV) return 0;
    return vs->fmt.frame_bytes <= vs->cap;
}

hal_status_t vision_source_init(vision_source_t *vs, hal_camera_t *camera, vision_detector_t *det, uint8_t *buf,
                                size_t cap)
{
    if (vs == NULL || camera == NULL || det == NULL || buf == NULL || cap == 0u) return HAL_E_ARG;
    memset(vs, 0, sizeof *vs);
    vs->src.ops = &vs_ops;
    vs->src.backend = vs;
    vs->camera = camera;
    vs->det = det;
    vs->buf = buf;
    vs->cap = cap;
    hal_status_t st = hal_camera_get_format(camera, &vs->fmt);
    if (st != HAL_OK) return st;
    if (!format_usable(vs)) return HAL_E_ARG;
    st = hal_camera_start(camera);
    return st;
}

static hal_status_t vs_next_frame(sighting_source_t *src, sighting_frame_t *out, uint32_t timeout_us)
{
    vision_source_t *vs = (vision_source_t *)src->backend;
    hal_camera_frame_info_t info;
    hal_status_t st = hal_camera_grab(vs->camera, vs->buf, vs->cap, &info, timeout_us);
    if (st == HAL_E_CLOSED) {
        /* not streaming (a failed start at init, or a stop): try again, once */
        if (hal_camera_start(vs->camera) != HAL_OK) {
            vs->ctr.grab_errors++;
            return HAL_E_CLOSED;
        }
        st = hal_camera_grab(vs->camera, vs->buf, vs->cap, &info, timeout_us);
    }
    if (st == HAL_E_TIMEOUT) {
        vs->ctr.grab_timeouts++;
        return HAL_E_TIMEOUT;
    }
    if (st != HAL_OK) {
        vs->ctr.grab_errors++;
        return st == HAL_E_CLOSED ? HAL_E_CLOSED : HAL_E_IO;
    }
    if (!format_usable(vs) || info.len < vs->fmt.frame_bytes) {
        vs->ctr.grab_errors++;
        return HAL_E_IO;
    }
    const vision_status_t vst = vs->fmt.pixfmt == HAL_CAMERA_PIX_RGB24
                                    ? vision_detect_rgb(vs->det, vs->buf, vs->fmt.stride_bytes, &vs->result)
                                    : vision_detect_yuyv(vs->det, vs->buf, vs->fmt.stride_bytes, &vs->result);
    if (vst == VISION_E_CAPACITY) {
        vs->ctr.detect_partial++;  /* the markers found in the part processed are still good */
    } else if (vst != VISION_OK) {
        vs->ctr.grab_errors++;
        return HAL_E_IO;
    }
    vs->ctr.frames++;
    memset(out, 0, sizeof *out);
    out->stamp_us = info.stamp_us;
    out->sequence = info.sequence;
    uint32_t dropped = vs->result.dropped;
    for (uint16_t i = 0; i < vs->result.n_markers; ++i) {
        const vision_marker_t *m = &vs->result.markers[i];
        if (m->kind == VISION_MARKER_LANDMARK) {
            if (out->n_landmarks >= COSLAM_MAX_SIGHTINGS) {
                dropped++;
                continue;
            }
            sighting_t *z = &out->landmarks[out->n_landmarks++];
            z->range_m = m->range_m;
            z->bearing_rad = m->bearing_rad;
            z->signature = m->index;
            vs->ctr.landmarks++;
        } else if (m->kind == VISION_MARKER_ROBOT) {
            if (m->index >= COSLAM_MAX_ROBOTS) {
                vs->ctr.foreign_robots++;
                continue;
            }
            if (out->n_robots >= COSLAM_MAX_ROBOTS) {
                dropped++;
                continue;
            }
            robot_seen_t *r = &out->robots[out->n_robots++];
            r->robot_id = m->index;
            r->range_m = m->range_m;
            r->bearing_rad = m->bearing_rad;
            vs->ctr.robots++;
        }
    }
    out->dropped = (uint16_t)(dropped > 0xFFFFu ? 0xFFFFu : dropped);
    vs->ctr.dropped += dropped;
    return HAL_OK;
}
