/*
 * Two processes, two robots, map messages over Cyclone DDS on loopback
 * (unicast discovery of 127.0.0.1, no multicast; domain 173 and a
 * partition named after the parent's pid, so parallel runs do not meet).
 * The process forks before touching DDS; each side opens its DDS link with
 * the authentication decorator in front, waits for the other, sends it
 * K map messages (up to COSLAM_MAX_MSG_LANDMARKS landmarks) and checks the
 * K it receives byte for byte against what the other side must have sent
 * (both derive the messages from the same seeds), then waits for its own
 * to be acknowledged. Exit status 0 on both sides = pass.
 */
#define _POSIX_C_SOURCE 200809L
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "hal/hal_link_auth.h"
#include "hal/hal_link_dds.h"
#include "link_test_util.h"

#define DOMAIN 173u
#define K 6
#define WAIT_US 10000000u

static hal_link_dds_t g_dds;
static hal_link_auth_t g_auth;
static uint8_t g_tx[MAP_MSG_MAX_BYTES], g_want[MAP_MSG_MAX_BYTES], g_rx[HAL_LINK_MAX_PAYLOAD];

#define CHECK(cond)                                                                    \
    do {                                                                               \
        if (!(cond)) {                                                                 \
            fprintf(stderr, "[robot %u] %s:%d: check failed: %s\n", self, __FILE__, __LINE__, #cond); \
            return 1;                                                                  \
        }                                                                              \
    } while (0)

static uint16_t n_landmarks(int k)
{
    const uint16_t n[K] = {0, 1, 3, 10, 20, LT_MAX_LANDMARKS};
    return n[k];
}

static int robot(unsigned self, unsigned peer, const char *partition)
{
    const char *peers[] = {"127.0.0.1", NULL};
    hal_link_dds_config_t c;
    memset(&c, 0, sizeof c);
    c.domain_id = DOMAIN;
    c.self_id = (uint16_t)self;
    c.peers = peers;
    c.config = LT_DDS_LOOPBACK_XML;
    c.partition = partition;
    c.history_depth = 16;
    CHECK(hal_link_dds_open(&g_dds, &c) == HAL_OK);
    hal_link_auth_config_t ac;
    memset(&ac, 0, sizeof ac);
    CHECK(hal_link_auth_key_from_hex("c0ffee00112233445566778899aabbccddeeff00112233445566778899aabbcc", ac.key) ==
          HAL_OK);
    ac.key_id = 3;
    hal_link_t *link = hal_link_auth_open(&g_dds.link, &ac, &g_auth);
    CHECK(link != NULL);
    CHECK(hal_link_dds_wait_matched(&g_dds, 1, WAIT_US) == HAL_OK);

    for (int k = 0; k < K; ++k) {
        const size_t L = lt_encode(g_tx, (uint8_t)self, (uint8_t)peer, n_landmarks(k), 100u * self + (uint64_t)k);
        CHECK(L > 0u);
        CHECK(hal_link_send(link, (uint16_t)peer, g_tx, L, 0) == HAL_OK);
    }
    /* reliable, one writer: in order */
    for (int k = 0; k < K; ++k) {
        hal_link_rx_info_t info;
        const size_t L = lt_encode(g_want, (uint8_t)peer, (uint8_t)self, n_landmarks(k), 100u * peer + (uint64_t)k);
        CHECK(hal_link_recv(link, g_rx, sizeof g_rx, &info, WAIT_US) == HAL_OK);
        CHECK(info.src_id == peer);
        CHECK(info.len == L);
        CHECK(memcmp(g_rx, g_want, L) == 0);
    }
    CHECK(hal_link_dds_flush(&g_dds, WAIT_US) == HAL_OK);
    const hal_link_auth_counters_t *a = hal_link_auth_counters(&g_auth);
    CHECK(a->sent == K && a->delivered == K);
    const hal_link_dds_counters_t *d = hal_link_dds_counters(&g_dds);
    CHECK(d->sent == K && d->delivered == K && d->rx_invalid == 0 && d->rx_own_id == 0);
    /* stay until the peer has had ours (it flushes before it exits, we wait
     * for its exit or a last datagram; simplest: a short grace period) */
    struct timespec ts = {0, 200 * 1000 * 1000};
    nanosleep(&ts, NULL);
    hal_link_close(link);
    printf("[robot %u] sent %d, received %d authenticated map messages byte-exact\n", self, K, K);
    return 0;
}

int main(void)
{
    unsetenv("CYCLONEDDS_URI");
    char partition[64];
    lt_partition(partition, sizeof partition, "2proc", (long)getpid());
    fflush(stdout);
    const pid_t child = fork(); /* before any DDS call: Cyclone's threads do not survive fork */
    if (child < 0) {
        perror("fork");
        return 1;
    }
    if (child == 0) {
        alarm(30); /* never outlive a hung parent */
        const int crc = robot(2, 1, partition);
        fflush(stdout);
        _exit(crc);
    }
    const int rc = robot(1, 2, partition);
    if (rc != 0) kill(child, SIGTERM);
    int status = 0;
    if (waitpid(child, &status, 0) != child) return 1;
    const int child_ok = WIFEXITED(status) && WEXITSTATUS(status) == 0;
    if (!child_ok) fprintf(stderr, "child robot failed (status %d)\n", status);
    return rc == 0 && child_ok ? 0 : 1;
}
