/* Sighting sources of coslam-robot: the choice and the landmark-log replay
 * (robot_sightings.h). */
#include "robot_sightings.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include "app/slam_params_ini.h"
#include "coslam/pose2.h"

/* ---- parsing ------------------------------------------------------------- */

typedef enum { LINE_SKIP = 0, LINE_RECORD = 1, LINE_BAD = 2 } line_kind_t;

/* Split a line into at most 6 blank-separated fields (in place). */
static int split(char *s, char **field, int max)
{
    int n = 0;
    char *p = s;
    while (*p != '\0') {
        while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n') {
            *p++ = '\0';
        }
        if (*p == '\0' || *p == '#') {
            break;
        }
        if (n == max) {
            return max + 1;
        }
        field[n++] = p;
        while (*p != '\0' && *p != ' ' && *p != '\t' && *p != '\r' && *p != '\n') {
            ++p;
        }
    }
    return n;
}

static line_kind_t parse_line(char *text, robot_replay_record_t *rec, char *why, size_t cap)
{
    char *f[6];
    const int n = split(text, f, 5);
    if (n == 0) {
        return LINE_SKIP;
    }
    const char tag = f[0][0];
    if (f[0][1] != '\0' || (tag != 'Z' && tag != 'R' && tag != 'O' && tag != 'V')) {
        (void)snprintf(why, cap, "unknown record type '%s' (expected Z, R, O or V)", f[0]);
        return LINE_BAD;
    }
    const int want = tag == 'V' ? 4 : 5;
    if (n != want) {
        (void)snprintf(why, cap, "%s", tag == 'Z'   ? "expected Z t id range bearing"
                                       : tag == 'R' ? "expected R t other_robot_id range bearing"
                                       : tag == 'O' ? "expected O t dx dy dtheta"
                                                    : "expected V t v w");
        return LINE_BAD;
    }
    double v[4] = {0.0, 0.0, 0.0, 0.0};
    for (int i = 1; i < n; ++i) {
        if (slam_params_ini_parse_number(f[i], &v[i - 1]) != COSLAM_OK) {
            (void)snprintf(why, cap, "field %d is not a finite number: '%s'", i + 1, f[i]);
            return LINE_BAD;
        }
    }
    if (!(v[0] >= 0.0 && v[0] < 1e9)) {
        (void)snprintf(why, cap, "time %s outside [0, 1e9) s", f[1]);
        return LINE_BAD;
    }
    rec->tag = tag;
    rec->t_us = (uint64_t)llround(v[0] * 1e6);
    if (tag == 'O' || tag == 'V') {
        return LINE_RECORD;
    }
    if (v[1] != floor(v[1]) || v[1] < -1.0 || v[1] > 1e9 || (tag == 'R' && v[1] < 0.0)) {
        (void)snprintf(why, cap, "%s must be an integer (%s), got '%s'", tag == 'Z' ? "id" : "other_robot_id",
                       tag == 'Z' ? "-1 or >= 0" : ">= 0", f[2]);
        return LINE_BAD;
    }
    if (tag == 'R' && v[1] >= (double)COSLAM_MAX_ROBOTS) {
        /* would be dropped at play time, said as a frame's capacity */
        (void)snprintf(why, cap, "other_robot_id %s is not a robot id of this build (0 .. %u)", f[2],
                       (unsigned)COSLAM_MAX_ROBOTS - 1U);
        return LINE_BAD;
    }
    if (!(v[2] > 0.0)) {
        (void)snprintf(why, cap, "range must be > 0, got '%s'", f[3]);
        return LINE_BAD;
    }
    rec->id = (int32_t)v[1];
    rec->range_m = v[2];
    rec->bearing_rad = angle_wrap(v[3]);
    return LINE_RECORD;
}

/* Next Z or R record of the current pass: 1, 0 at the end of the file. */
static int read_record(robot_replay_t *r, robot_replay_record_t *rec)
{
    char buf[512];
    while (fgets(buf, sizeof buf, r->f) != NULL) {
        r->line++;
        char why[160];
        const line_kind_t k = parse_line(buf, rec, why, sizeof why);
        if (k != LINE_RECORD) {
            continue; /* comments; the file was checked at open */
        }
        if (rec->tag == 'O' || rec->tag == 'V') {
            r->ignored_records++;
            continue;
        }
        return 1;
    }
    return 0;
}

/* ---- the source ---------------------------------------------------------- */

static void frame_clear(sighting_frame_t *fr)
{
    memset(fr, 0, sizeof *fr);
}

static void add_record(robot_replay_t *r, const robot_replay_record_t *rec)
{
    sighting_frame_t *fr = &r->building;
    if (r->building_n == 0) {
        frame_clear(fr);
        r->building_t_us = rec->t_us;
        fr->stamp_us = r->base_us + rec->t_us;
    }
    r->building_n++;
    r->records++;
    if (rec->tag == 'Z') {
        if (fr->n_landmarks < COSLAM_MAX_SIGHTINGS) {
            sighting_t *z = &fr->landmarks[fr->n_landmarks++];
            z->range_m = rec->range_m;
            z->bearing_rad = rec->bearing_rad;
            z->signature = 0U; /* non-unique markers: the id is ground truth only */
        } else {
            fr->dropped++;
        }
    } else {
        if (fr->n_robots < COSLAM_MAX_ROBOTS && rec->id < COSLAM_MAX_ROBOTS) {
            robot_seen_t *s = &fr->robots[fr->n_robots++];
            s->robot_id = (uint8_t)rec->id;
            s->range_m = rec->range_m;
            s->bearing_rad = rec->bearing_rad;
        } else {
            fr->dropped++;
        }
    }
}

static void complete_frame(robot_replay_t *r)
{
    if (r->building_n == 0) {
        return;
    }
    if (r->ready) {
        r->frames_skipped++;
    }
    r->building.sequence = ++r->sequence;
    r->out = r->building;
    r->ready = 1;
    r->building_n = 0;
}

/* A parsed record against the fleet: LINE_RECORD, or LINE_BAD with why. A
 * robot sighting of this robot itself, or of an id outside the fleet,
 * would go to the meeting as a partner no link can reach (and a robot
 * never sees its own marker): a bad line, like an id no robot of the
 * build can have (the log refuses it at open, the live stream the record). */
static line_kind_t check_robot_id(const robot_replay_record_t *rec, uint8_t own_id, uint8_t fleet_size, char *why,
                                  size_t cap)
{
    if (rec->tag != 'R') {
        return LINE_RECORD;
    }
    if (rec->id == (int32_t)own_id) {
        (void)snprintf(why, cap, "other_robot_id %ld is this robot's own id ([robot] id = %u): a robot does not "
                       "see itself", (long)rec->id, (unsigned)own_id);
        return LINE_BAD;
    }
    if (rec->id >= (int32_t)fleet_size) {
        (void)snprintf(why, cap, "other_robot_id %ld is not in the fleet ([robot] fleet_size = %u: ids 0 .. %u)",
                       (long)rec->id, (unsigned)fleet_size, (unsigned)fleet_size - 1U);
        return LINE_BAD;
    }
    return LINE_RECORD;
}

/* ... and against the log so far: t must not decrease. */
static line_kind_t check_record(const robot_replay_record_t *rec, uint64_t last_t_us, uint8_t own_id,
                                uint8_t fleet_size, char *why, size_t cap)
{
    if (rec->t_us < last_t_us) {
        (void)snprintf(why, cap, "time goes backwards");
        return LINE_BAD;
    }
    return check_robot_id(rec, own_id, fleet_size, why, cap);
}

/* One datagram of the live stream into r->building; 1 if it is a frame. */
static int live_parse(robot_replay_t *r, char *text)
{
    int have_t = 0;
    uint64_t stamp = 0;
    r->building_n = 0;
    frame_clear(&r->building);
    for (char *line = text, *next = NULL; line != NULL && *line != '\0'; line = next) {
        next = strchr(line, '\n');
        if (next != NULL) {
            *next++ = '\0';
        }
        if (line[0] == 'T' && line[1] == ' ') {
            char *end = NULL;
            errno = 0;
            const unsigned long long v = strtoull(line + 2, &end, 10);
            if (errno != 0 || end == line + 2) {
                return 0;
            }
            stamp = (uint64_t)v;
            have_t = 1;
            continue;
        }
        if (line[0] == 'S' && line[1] == ' ') {
            /* S t signature range bearing: a marker of that class (the
             * camera's view: signature, no identity) */
            line[0] = 'Z';
            robot_replay_record_t rec;
            char why[160];
            if (parse_line(line, &rec, why, sizeof why) != LINE_RECORD || rec.id < 0 || rec.id > 255) {
                return 0;
            }
            const uint16_t before = r->building_n > 0 ? r->building.n_landmarks : 0U;
            add_record(r, &rec);
            sighting_frame_t *fr = &r->building;
            if (fr->n_landmarks > before) {
                fr->landmarks[fr->n_landmarks - 1U].signature = (uint8_t)rec.id;
            }
            continue;
        }
        robot_replay_record_t rec;
        char why[160];
        const line_kind_t k = parse_line(line, &rec, why, sizeof why);
        if (k == LINE_BAD) {
            return 0;
        }
        if (k == LINE_RECORD && rec.tag == 'R' &&
            check_robot_id(&rec, r->own_id, r->fleet_size, why, sizeof why) != LINE_RECORD) {
            /* as the log refuses it at open: the record, not the frame
             * (its other sightings are good); counted, the first said */
            if (r->live_robots_refused++ == 0U) {
                (void)snprintf(r->live_refused_why, sizeof r->live_refused_why, "%s", why);
            }
            continue;
        }
        if (k == LINE_RECORD && (rec.tag == 'Z' || rec.tag == 'R')) {
            add_record(r, &rec);
        }
    }
    if (!have_t) {
        return 0;
    }
    r->building.stamp_us = stamp;
    r->building_n = 1; /* an empty frame is a frame too: the camera saw nothing */
    return 1;
}

static hal_status_t live_next_frame(robot_replay_t *r, sighting_frame_t *out)
{
    if (r->live_fd < 0) {
        return HAL_E_CLOSED;
    }
    char buf[8192];
    for (int guard = 0; guard < 1000; ++guard) {
        const ssize_t n = recv(r->live_fd, buf, sizeof buf - 1u, MSG_DONTWAIT);
        if (n < 0) {
            if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) {
                break;
            }
            return HAL_E_IO;
        }
        if (n == 0) {
            return HAL_E_CLOSED;
        }
        buf[n] = '\0';
        if (!live_parse(r, buf)) {
            r->live_bad++;
            r->building_n = 0;
            continue;
        }
        complete_frame(r);
    }
    if (!r->ready) {
        return HAL_E_TIMEOUT;
    }
    *out = r->out;
    r->ready = 0;
    r->frames_given++;
    return HAL_OK;
}

static hal_status_t replay_next_frame(sighting_source_t *src, sighting_frame_t *out, uint32_t timeout_us)
{
    robot_replay_t *r = (robot_replay_t *)src->backend;
    (void)timeout_us; /* frames come at log times: waiting would only delay the caller */
    if (r->live) {
        return live_next_frame(r, out);
    }
    if (r->f == NULL) {
        return HAL_E_CLOSED;
    }
    uint64_t now = 0;
    if (hal_clock_now_us(r->clock, &now) != HAL_OK) {
        return HAL_E_IO;
    }
    for (int guard = 0; guard < 100000; ++guard) {
        if (!r->have_next) {
            if (read_record(r, &r->next)) {
                r->have_next = 1;
            } else {
                complete_frame(r);
                if (!r->loop || r->records == 0U) {
                    break;
                }
                /* again from the start, after the gap */
                if (fseek(r->f, 0L, SEEK_SET) != 0) {
                    return HAL_E_IO;
                }
                r->line = 0U;
                r->base_us += r->last_t_us + ROBOT_REPLAY_LOOP_GAP_US;
                r->loops++;
                continue;
            }
        }
        if (r->base_us + r->next.t_us > now) {
            complete_frame(r); /* the next record is later: the frame is whole */
            break;
        }
        if (r->building_n > 0 && r->next.t_us != r->building_t_us) {
            complete_frame(r);
        }
        add_record(r, &r->next);
        r->have_next = 0;
    }
    if (!r->ready) {
        return HAL_E_TIMEOUT;
    }
    *out = r->out;
    r->ready = 0;
    r->frames_given++;
    return HAL_OK;
}

static const sighting_source_ops_t replay_ops = {replay_next_frame};

hal_status_t robot_replay_open(robot_replay_t *r, const char *path, int loop, uint8_t own_id, uint8_t fleet_size,
                               hal_clock_t *clock, char *msg, size_t msg_cap)
{
    if (msg != NULL && msg_cap > 0U) {
        msg[0] = '\0';
    }
    if (r == NULL || path == NULL || clock == NULL || msg == NULL) {
        return HAL_E_ARG;
    }
    memset(r, 0, sizeof *r);
    r->src.ops = &replay_ops;
    r->src.backend = r;
    r->clock = clock;
    r->loop = loop != 0;
    (void)snprintf(r->path, sizeof r->path, "%s", path);
    FILE *f = fopen(path, "r");
    if (f == NULL) {
        const int e = errno;
        (void)snprintf(msg, msg_cap, "%s: %s", path, strerror(e));
        return e == ENOENT ? HAL_E_NOT_FOUND : HAL_E_IO;
    }
    /* the log is checked whole, then rewound: a FIFO (or any stream) can
     * be read once only, so it could never play; refused by name instead
     * of the rewind's "read error" (its open still waits for a writer) */
    struct stat sb;
    const int known = fstat(fileno(f), &sb) == 0;
    if (!known || !S_ISREG(sb.st_mode)) {
        (void)snprintf(msg, msg_cap,
                       "%s: not a regular file (%s): a replay log must be a file (it is checked whole, then rewound)",
                       path, known && S_ISFIFO(sb.st_mode) ? "a FIFO" : "not a plain file");
        (void)fclose(f);
        return HAL_E_UNSUPPORTED;
    }
    /* check the whole log now: a bad line is refused with its place */
    char buf[512];
    unsigned line = 0;
    uint64_t last = 0;
    while (fgets(buf, sizeof buf, f) != NULL) {
        line++;
        if (strchr(buf, '\n') == NULL && !feof(f)) {
            (void)snprintf(msg, msg_cap, "%s:%u: line longer than %zu characters", path, line, sizeof buf - 2U);
            (void)fclose(f);
            return HAL_E_CORRUPT;
        }
        robot_replay_record_t rec;
        char why[160];
        line_kind_t k = parse_line(buf, &rec, why, sizeof why);
        if (k == LINE_RECORD) {
            k = check_record(&rec, last, own_id, fleet_size, why, sizeof why);
        }
        if (k == LINE_BAD) {
            (void)snprintf(msg, msg_cap, "%s:%u: %s", path, line, why);
            (void)fclose(f);
            return HAL_E_CORRUPT;
        }
        if (k == LINE_RECORD) {
            last = rec.t_us;
        }
    }
    if (ferror(f) || fseek(f, 0L, SEEK_SET) != 0) {
        (void)snprintf(msg, msg_cap, "%s: read error", path);
        (void)fclose(f);
        return HAL_E_IO;
    }
    uint64_t now = 0;
    if (hal_clock_now_us(clock, &now) != HAL_OK) {
        (void)fclose(f);
        (void)snprintf(msg, msg_cap, "%s: the clock failed", path);
        return HAL_E_IO;
    }
    r->f = f;
    r->last_t_us = last;
    r->base_us = now;
    return HAL_OK;
}

hal_status_t robot_live_open(robot_replay_t *r, int fd, uint8_t own_id, uint8_t fleet_size, hal_clock_t *clock,
                             char *msg, size_t msg_cap)
{
    if (msg != NULL && msg_cap > 0U) {
        msg[0] = '\0';
    }
    if (r == NULL || clock == NULL || msg == NULL || fd < 0) {
        return HAL_E_ARG;
    }
    memset(r, 0, sizeof *r);
    r->src.ops = &replay_ops;
    r->src.backend = r;
    r->clock = clock;
    r->live = 1;
    r->own_id = own_id;
    r->fleet_size = fleet_size;
    (void)snprintf(r->path, sizeof r->path, "fd %d", fd);
    r->live_fd = dup(fd);
    if (r->live_fd < 0) {
        (void)snprintf(msg, msg_cap, "sightings fd %d: %s", fd, strerror(errno));
        return HAL_E_IO;
    }
    return HAL_OK;
}

void robot_replay_close(robot_replay_t *r)
{
    if (r != NULL && r->live && r->live_fd >= 0) {
        (void)close(r->live_fd);
        r->live_fd = -1;
    }
    if (r != NULL && r->f != NULL) {
        (void)fclose(r->f);
        r->f = NULL;
    }
}

void robot_replay_move(robot_replay_t *to, robot_replay_t *from)
{
    *to = *from;
    to->src.backend = to;
    from->f = NULL;
    from->live_fd = -1;
}

robot_sightings_kind_t robot_sightings_kind(const robot_config_t *cfg)
{
    /* ---- SIGHTING SOURCE CHOICE ------------------------------------------ */
    if (cfg->camera_live_fd >= 0) {
        return ROBOT_SIGHTINGS_LIVE;
    }
    if (cfg->camera_replay_log[0] != '\0') {
        return ROBOT_SIGHTINGS_REPLAY;
    }
    if (cfg->camera_device[0] == '\0') {
        return ROBOT_SIGHTINGS_NONE;
    }
    return COSLAM_HAVE_CAMERA ? ROBOT_SIGHTINGS_CAMERA : ROBOT_SIGHTINGS_NO_CAMERA;
}

robot_sightings_kind_t robot_open_sightings(robot_replay_t *r, const robot_config_t *cfg, hal_clock_t *clock,
                                            hal_status_t *st, char *msg, size_t msg_cap)
{
    *st = HAL_E_UNSUPPORTED;
    if (msg != NULL && msg_cap > 0U) {
        msg[0] = '\0';
    }
    const robot_sightings_kind_t k = robot_sightings_kind(cfg);
    if (k == ROBOT_SIGHTINGS_LIVE) {
        *st = robot_live_open(r, cfg->camera_live_fd, cfg->robot_id, cfg->fleet_size, clock, msg, msg_cap);
    } else if (k == ROBOT_SIGHTINGS_REPLAY) {
        *st = robot_replay_open(r, cfg->camera_replay_log, cfg->camera_replay_loop, cfg->robot_id, cfg->fleet_size,
                                clock, msg, msg_cap);
    }
    return k;
}

int robot_live_say_refusals(robot_replay_t *r, FILE *out)
{
    if (r == NULL || !r->live || r->live_robots_refused == 0U || r->live_refusals_said) {
        return 0;
    }
    r->live_refusals_said = 1;
    fprintf(out,
            "coslam-robot: sightings %s: robot sightings refused: %s (the first; live_robots_refused counts them, "
            "the others are not said)\n",
            r->path, r->live_refused_why);
    return 1;
}
