/* The link backend of coslam-robot: policy, fleet key, DDS and the
 * authentication decorator (robot_link.h). */
#include "robot_link.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#if COSLAM_HAVE_LINK_AUTH
#include <sodium.h>
#endif

/* snprintf that may truncate on purpose (messages, labels): always terminated. */
__attribute__((format(printf, 3, 4))) static void put_text(char *dst, size_t cap, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    (void)vsnprintf(dst, cap, fmt, ap);
    va_end(ap);
}

#if COSLAM_HAVE_DDS && COSLAM_HAVE_LINK_AUTH
/* 1 if gid is this process's group or one of its supplementary groups. */
static int in_own_groups(gid_t gid)
{
    if (gid == getegid()) {
        return 1;
    }
    gid_t groups[256];
    const int n = getgroups((int)(sizeof groups / sizeof groups[0]), groups);
    for (int i = 0; i < n; ++i) {
        if (groups[i] == gid) {
            return 1;
        }
    }
    return 0;
}

/* The fleet key file: a regular file of 64 hex digits (white space around
 * them allowed), readable by this process, not writable by its group and
 * not accessible to others at all. Group read is allowed on purpose: the
 * Debian package installs the key root:coslam 0640 for the coslam service
 * user (firmware/port/linux/dist/debian/postinst), so only by a group this
 * process is in; and the owner is root or this process's user (anyone else
 * could rewrite the key it trusts). No NUL byte. Returns 0, or -1 with
 * `why`; never echoes the content. Every buffer that held key text is
 * wiped. */
static int read_key_file(const char *path, uint8_t key[HAL_LINK_AUTH_KEY_BYTES], char *why, size_t cap)
{
    /* O_NONBLOCK: a FIFO planted at the path must not hang the start */
    const int fd = open(path, O_RDONLY | O_CLOEXEC | O_NOCTTY | O_NONBLOCK);
    if (fd < 0) {
        const int e = errno;
        if (e == ENOENT) {
            put_text(why, cap, "no such file");
        } else if (e == EACCES) {
            put_text(why, cap, "permission denied (this robot's user cannot read it)");
        } else {
            put_text(why, cap, "cannot open it: %s", strerror(e));
        }
        return -1;
    }
    struct stat sb;
    if (fstat(fd, &sb) != 0) {
        put_text(why, cap, "cannot stat it: %s", strerror(errno));
        (void)close(fd);
        return -1;
    }
    const unsigned mode = (unsigned)sb.st_mode & 07777U;
    int bad = 0;
    if (!S_ISREG(sb.st_mode)) {
        put_text(why, cap, "not a regular file");
        bad = 1;
    } else if ((mode & (unsigned)S_IRWXO) != 0U) {
        put_text(why, cap, "accessible to others (mode %04o): chmod 600 (or 640 with the robot's group)", mode);
        bad = 1;
    } else if ((mode & (unsigned)S_IWGRP) != 0U) {
        put_text(why, cap, "writable by its group (mode %04o): chmod 600 or 640", mode);
        bad = 1;
    } else if (sb.st_uid != 0 && sb.st_uid != geteuid()) {
        /* its owner could rewrite the key this robot trusts */
        put_text(why, cap, "owned by uid %lu, neither root nor this robot's user: chown root", (unsigned long)sb.st_uid);
        bad = 1;
    } else if ((mode & (unsigned)S_IRGRP) != 0U && !in_own_groups(sb.st_gid)) {
        put_text(why, cap,
                 "readable by group %lu, which this robot's user is not in (mode %04o): chmod 600, or chgrp to "
                 "the robot's group",
                 (unsigned long)sb.st_gid, mode);
        bad = 1;
    }
    if (bad) {
        (void)close(fd);
        return -1;
    }
    /* 64 digits and some white space; anything longer is not a key */
    char text[160];
    size_t n = 0;
    int rc = 0;
    for (;;) {
        const ssize_t r = read(fd, text + n, sizeof text - 1U - n);
        if (r < 0 && errno == EINTR) {
            continue;
        }
        if (r < 0) {
            put_text(why, cap, "read error: %s", strerror(errno));
            rc = -1;
            break;
        }
        if (r == 0) {
            break;
        }
        n += (size_t)r;
        if (n == sizeof text - 1U) {
            char extra = 0;
            if (read(fd, &extra, 1U) > 0) {
                put_text(why, cap, "not a fleet key (expected 64 hexadecimal digits; the file is longer)");
                rc = -1;
            }
            sodium_memzero(&extra, sizeof extra);
            break;
        }
    }
    (void)close(fd);
    text[n] = '\0';
    if (rc == 0 && memchr(text, '\0', n) != NULL) {
        /* the hex parser would stop there and take what follows for nothing */
        put_text(why, cap, "not a fleet key (a NUL byte in the file; expected 64 hexadecimal digits)");
        rc = -1;
    } else if (rc == 0 && hal_link_auth_key_from_hex(text, key) != HAL_OK) {
        put_text(why, cap, "not a fleet key (expected 64 hexadecimal digits, white space around them allowed)");
        rc = -1;
    }
    sodium_memzero(text, sizeof text);
    return rc;
}
#endif

coslam_status_t robot_open_link(robot_link_t *l, const robot_config_t *cfg, hal_link_t *slot, char *msg,
                                size_t msg_cap)
{
    if (l == NULL || cfg == NULL || slot == NULL || msg == NULL) {
        return COSLAM_E_ARG;
    }
    memset(l, 0, sizeof *l);
    msg[0] = '\0';
    l->slot = slot;
    l->node_link = hal_link_null();
    l->mode = ROBOT_LINK_OFF;
    (void)msg_cap;
    /* ---- LINK BACKEND CHOICE (the one place; policy in robot_link.h) ---- */
#if !COSLAM_HAVE_DDS
    (void)cfg;
    l->off_reason = "no DDS in this build";
    put_text(l->what, sizeof l->what, "null: built without Cyclone DDS, no map exchange");
    return COSLAM_OK;
#else
    COSLAM_ASSERT(strcmp(ROBOT_CONFIG_DEFAULT_TOPIC, HAL_LINK_DDS_DEFAULT_TOPIC) == 0);
    hal_link_dds_config_t *d = &l->dds_cfg;
    d->domain_id = cfg->link_domain;
    d->self_id = cfg->robot_id;
    put_text(l->peer_text, sizeof l->peer_text, "%s", cfg->link_peers);
    size_t n_peers = 0;
    /* the config stored them checked and normalised: "a, b, c" */
    for (char *p = l->peer_text; *p != '\0' && n_peers < ROBOT_CONFIG_MAX_PEERS;) {
        l->peers[n_peers++] = p;
        char *comma = strchr(p, ',');
        if (comma == NULL) {
            break;
        }
        *comma = '\0';
        p = comma + 1;
        while (*p == ' ') {
            ++p;
        }
    }
    l->peers[n_peers] = NULL;
    d->peers = n_peers > 0U ? l->peers : NULL;
    d->config = cfg->link_config[0] != '\0' ? cfg->link_config : NULL;
    d->partition = cfg->link_partition[0] != '\0' ? cfg->link_partition : NULL;
    d->topic = cfg->link_topic;
    d->history_depth = cfg->link_history_depth;
    d->send_block_us = 0U; /* never block the control loop: HAL_E_BUSY, counted */
    char where[300];
    put_text(where, sizeof where, "Cyclone DDS domain %lu, topic %s, partition %s, %s%s", (unsigned long)d->domain_id,
             d->topic, d->partition != NULL ? d->partition : "(default)",
             n_peers > 0U ? "peers " : "multicast discovery", n_peers > 0U ? cfg->link_peers : "");

    if (cfg->link_insecure) {
        l->mode = ROBOT_LINK_INSECURE;
        l->node_link = slot;
        put_text(l->what, sizeof l->what, "%s, UNAUTHENTICATED", where);
        return COSLAM_OK;
    }
#if !COSLAM_HAVE_LINK_AUTH
    l->off_reason = "no authentication in this build";
    put_text(l->what, sizeof l->what,
             "null: built without libsodium, so no authentication and no map exchange "
             "([link] insecure = true runs DDS unauthenticated)");
    return COSLAM_OK;
#else
    if (cfg->fleet_key_file[0] == '\0') {
        l->off_reason = "no fleet key";
        put_text(l->what, sizeof l->what, "null: no fleet key ([fleet] key_file is empty), no map exchange");
        return COSLAM_OK;
    }
    hal_link_auth_config_t ac;
    memset(&ac, 0, sizeof ac);
    char why[200];
    if (read_key_file(cfg->fleet_key_file, ac.key, why, sizeof why) != 0) {
        sodium_memzero(&ac, sizeof ac);
        put_text(msg, msg_cap,
                 "[fleet] key_file %s: %s; the robot does not start without its fleet key (an empty key_file "
                 "runs it without a link; docs/robot.md, \"The link\")",
                 cfg->fleet_key_file, why);
        return COSLAM_E_ARG;
    }
    ac.key_id = cfg->fleet_key_id;
    ac.window_us = (uint64_t)llround(cfg->fleet_window_s * 1e6);
    hal_link_t *top = hal_link_auth_open(slot, &ac, &l->auth);
    sodium_memzero(&ac, sizeof ac);
    if (top == NULL) {
        put_text(msg, msg_cap, "link: the authentication could not start (libsodium initialisation failed)");
        return COSLAM_E_LINK;
    }
    l->auth_open = 1;
    l->mode = ROBOT_LINK_AUTH;
    l->node_link = top;
    put_text(l->what, sizeof l->what, "%s, authenticated with key id %u", where, (unsigned)cfg->fleet_key_id);
    return COSLAM_OK;
#endif
#endif
}

hal_link_t *robot_link_handle(robot_link_t *l)
{
    return l->node_link;
}

#if COSLAM_HAVE_DDS
/* Every "file://" entry of a Cyclone configuration list (`text`, comma-
 * separated, named `key` in messages) names a file that can be read:
 * HAL_OK, or HAL_E_NOT_FOUND / HAL_E_IO with the key, the entry, the path
 * and the OS's reason in `reason`. Cyclone itself only answers that the
 * domain could not be made (HAL_E_IO), with no word about the file. */
static hal_status_t config_files_readable(const char *text, const char *key, char *reason, size_t cap)
{
    for (const char *p = text; p != NULL && *p != '\0';) {
        while (*p == ' ' || *p == '\t') {
            ++p;
        }
        const char *end = strchr(p, ',');
        size_t len = end != NULL ? (size_t)(end - p) : strlen(p);
        while (len > 0U && (p[len - 1U] == ' ' || p[len - 1U] == '\t')) {
            --len;
        }
        if (len > 7U && strncmp(p, "file://", 7U) == 0) {
            char path[ROBOT_CONFIG_PATH_MAX + 1u];
            put_text(path, sizeof path, "%.*s", (int)(len - 7U), p + 7);
            /* O_NONBLOCK: a FIFO must not hold the opener here */
            const int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
            struct stat sb;
            const int e = fd < 0 ? errno : fstat(fd, &sb) != 0 ? errno : S_ISREG(sb.st_mode) ? 0 : -1;
            if (fd >= 0) {
                (void)close(fd);
            }
            if (e != 0) {
                const hal_status_t s = e == ENOENT ? HAL_E_NOT_FOUND : HAL_E_IO;
                put_text(reason, cap, "%s %.*s: cannot read %s: %s (%s)", key, (int)len, p, path,
                         e > 0 ? strerror(e) : "not a regular file", hal_status_str(s));
                return s;
            }
        }
        p = end != NULL ? end + 1 : NULL;
    }
    return HAL_OK;
}
#endif

hal_status_t robot_link_backend_open_device(robot_link_t *l, char *reason, size_t reason_cap)
{
    if (reason != NULL && reason_cap > 0U) {
        reason[0] = '\0';
    }
    if (l->mode == ROBOT_LINK_OFF) {
        return HAL_E_UNSUPPORTED;
    }
#if COSLAM_HAVE_DDS
    if (l->backend_open) {
        return HAL_OK;
    }
    /* the configuration files first, named (hal_link_dds.h: CYCLONEDDS_URI,
     * then [link] config) */
    char unused[1];
    char *why = reason != NULL ? reason : unused;
    const size_t why_cap = reason != NULL ? reason_cap : sizeof unused;
    hal_status_t fs = config_files_readable(getenv("CYCLONEDDS_URI"), "CYCLONEDDS_URI (environment)", why, why_cap);
    if (fs == HAL_OK) {
        fs = config_files_readable(l->dds_cfg.config, "[link] config", why, why_cap);
    }
    if (fs != HAL_OK) {
        return fs;
    }
    const hal_status_t s = hal_link_dds_open(&l->dds, &l->dds_cfg);
    if (s == HAL_OK) {
        return HAL_OK;
    }
    if (reason != NULL) {
        const char *w = s == HAL_E_ARG    ? "bad setting (peer address, or the Cyclone configuration is too long)"
                        : s == HAL_E_BUSY ? "the DDS domain is busy in this process"
                        : s == HAL_E_IO   ? "Cyclone DDS refused (bad [link] config or CYCLONEDDS_URI, no usable "
                                            "network interface, ...)"
                                          : "failed";
        put_text(reason, reason_cap, "%s (%s)", w, hal_status_str(s));
    }
    return s;
#else
    return HAL_E_UNSUPPORTED;
#endif
}

void robot_link_backend_opened(robot_link_t *l)
{
#if COSLAM_HAVE_DDS
    l->backend_open = 1;
#else
    (void)l;
#endif
}

hal_link_t *robot_link_backend(robot_link_t *l)
{
#if COSLAM_HAVE_DDS
    return l->backend_open ? &l->dds.link : NULL;
#else
    (void)l;
    return NULL;
#endif
}

#if COSLAM_HAVE_DDS
static void add_dds(hal_link_dds_counters_t *a, const hal_link_dds_counters_t *b)
{
    a->sent += b->sent;
    a->send_not_map += b->send_not_map;
    a->send_trailer_too_long += b->send_trailer_too_long;
    a->send_busy += b->send_busy;
    a->send_io += b->send_io;
    a->delivered += b->delivered;
    a->rx_overflow += b->rx_overflow;
    a->rx_other_dest += b->rx_other_dest;
    a->rx_own_id += b->rx_own_id;
    a->rx_invalid += b->rx_invalid;
    a->rx_not_data += b->rx_not_data;
    a->dds_lost += b->dds_lost;
    a->dds_rejected += b->dds_rejected;
    a->rx_io += b->rx_io;
}
#endif

void robot_link_backend_close(robot_link_t *l)
{
#if COSLAM_HAVE_DDS
    if (l->backend_open) {
        add_dds(&l->dds_closed, hal_link_dds_counters(&l->dds));
        hal_link_close(&l->dds.link);
        l->backend_open = 0;
    }
#else
    (void)l;
#endif
}

void robot_link_flush(robot_link_t *l, uint32_t timeout_us)
{
#if COSLAM_HAVE_DDS
    if (l->backend_open) {
        (void)hal_link_dds_flush(&l->dds, timeout_us);
    }
#else
    (void)l;
    (void)timeout_us;
#endif
}

void robot_close_link(robot_link_t *l)
{
#if COSLAM_HAVE_LINK_AUTH
    if (l->auth_open) {
        hal_link_close(&l->auth.link); /* wipes the key; the slot has no close of its own */
        l->auth_open = 0;
    }
#endif
    robot_link_backend_close(l);
    l->node_link = hal_link_null();
}

const char *robot_link_mode_name(const robot_link_t *l)
{
    switch (l->mode) {
    case ROBOT_LINK_AUTH: return "auth";
    case ROBOT_LINK_INSECURE: return "insecure";
    case ROBOT_LINK_OFF: break;
    }
    if (l->off_reason != NULL && strcmp(l->off_reason, "no fleet key") == 0) {
        return "off(no_fleet_key)";
    }
    if (l->off_reason != NULL && strcmp(l->off_reason, "no authentication in this build") == 0) {
        return "off(no_auth_in_build)";
    }
    return "off(no_dds_in_build)";
}

const char *robot_link_warning(const robot_link_t *l)
{
    switch (l->mode) {
    case ROBOT_LINK_AUTH: return NULL;
    case ROBOT_LINK_INSECURE: return "link: INSECURE (DDS without authentication: [link] insecure = true)";
    case ROBOT_LINK_OFF: break;
    }
    if (l->off_reason != NULL && strcmp(l->off_reason, "no fleet key") == 0) {
        return "link: off (no fleet key)";
    }
    if (l->off_reason != NULL && strcmp(l->off_reason, "no authentication in this build") == 0) {
        return "link: off (built without libsodium: no authentication)";
    }
    return "link: off (built without Cyclone DDS)";
}

void robot_link_counters(const robot_link_t *l, robot_link_counters_t *o)
{
    memset(o, 0, sizeof *o);
#if COSLAM_HAVE_DDS
    hal_link_dds_counters_t d = l->dds_closed;
    if (l->backend_open) {
        add_dds(&d, hal_link_dds_counters(&l->dds));
    }
    o->dds_sent = d.sent;
    o->dds_send_not_map = d.send_not_map;
    o->dds_send_trailer_too_long = d.send_trailer_too_long;
    o->dds_send_busy = d.send_busy;
    o->dds_send_io = d.send_io;
    o->dds_delivered = d.delivered;
    o->dds_rx_overflow = d.rx_overflow;
    o->dds_rx_other_dest = d.rx_other_dest;
    o->dds_rx_own_id = d.rx_own_id;
    o->dds_rx_invalid = d.rx_invalid;
    o->dds_rx_not_data = d.rx_not_data;
    o->dds_lost = d.dds_lost;
    o->dds_rejected = d.dds_rejected;
    o->dds_rx_io = d.rx_io;
#endif
#if COSLAM_HAVE_LINK_AUTH
    if (l->mode == ROBOT_LINK_AUTH) {
        const hal_link_auth_counters_t *a = hal_link_auth_counters(&l->auth);
        o->auth_sent = a->sent;
        o->auth_send_not_map = a->send_not_map;
        o->auth_send_wrong_sender = a->send_wrong_sender;
        o->auth_send_too_long = a->send_too_long;
        o->auth_send_inner_failed = a->send_inner_failed;
        o->auth_delivered = a->delivered;
        o->auth_rx_overflow = a->rx_overflow;
        o->auth_rx_malformed = a->rx_malformed;
        o->auth_rx_unauthenticated = a->rx_unauthenticated;
        o->auth_rx_truncated = a->rx_truncated;
        o->auth_rx_wrong_key = a->rx_wrong_key;
        o->auth_rx_bad_mac = a->rx_bad_mac;
        o->auth_rx_sender_mismatch = a->rx_sender_mismatch;
        o->auth_rx_stale = a->rx_stale;
        o->auth_rx_future = a->rx_future;
        o->auth_rx_replay = a->rx_replay;
        o->auth_rx_oversize = a->rx_oversize;
        o->auth_refused = a->rx_malformed + a->rx_unauthenticated + a->rx_truncated + a->rx_wrong_key + a->rx_bad_mac +
                          a->rx_sender_mismatch + a->rx_stale + a->rx_future + a->rx_replay + a->rx_oversize;
    }
#endif
#if !COSLAM_HAVE_DDS && !COSLAM_HAVE_LINK_AUTH
    (void)l;
#endif
}
