/*
 * libFuzzer target for the CANopen / CiA 402 frame handling
 * (firmware/drivers/cia402: canopen.c, cia402.c, cia402_drive.c).
 *
 * The input is a script of 12-byte records, each one received frame plus
 * what the owner does around it, for one drive (node 3) that has been
 * started (bring-up at BOOT):
 *   r[0] bits 0-2  the frame: 0 heartbeat 0x703, 1 SDO reply 0x583,
 *                  2 TPDO1 0x183, 3 EMCY 0x083, 4 SDO reply of node 5,
 *                  5 raw 11-bit id (r[0] bits 3-5 : r[3]), 6 NMT 0x000,
 *                  7 extended id 0x583 (not CANopen)
 *        bit 6     remote frame; bit 7: the next send fails (HAL_E_TIMEOUT)
 *   r[1] bits 0-3  dlc (mod 9); bits 4-7 the owner's action before the
 *                  frame: 1 goal ENABLED, 2 goal DISABLED, 3 goal
 *                  QUICK_STOP, 4 target velocity (data bytes 0-3),
 *                  5 fault reset, 6 user SDO read, 7 user SDO write,
 *                  8 restart, 9 bus error; others nothing
 *   r[2]           time step before the frame [ms]
 *   r[3]           SDO sub-index of the action, id bits for kind 5
 *   r[4..11]       data bytes
 * After each frame the driver is polled.
 * Seeds (corpus/fuzz_cia402/, corpus/make_seeds.py): a complete bring-up
 * to OPERATION_ENABLED, then TPDOs, EMCYs, an SDO abort, lost heartbeats.
 *
 * Properties checked, beyond "no crash, no ASan/UBSan report":
 *  - the pure parsers: an SDO reply / EMCY of dlc != 8, a heartbeat of
 *    dlc != 1, a TPDO of dlc != 6 is COSLAM_E_DRIVE_PROTOCOL; an expedited
 *    upload has size 1..4 and a value that fits in size bytes; a heartbeat
 *    state fits in 7 bits;
 *  - a frame of another node, an extended or a remote frame returns
 *    NOT_MINE and leaves the drive state byte-for-byte unchanged;
 *  - RX_TPDO only for a TPDO1 of this node with dlc 6;
 *  - every frame the driver sends is a valid standard frame addressed to
 *    node 3 (NMT with node 3, RPDO1 0x203 dlc 6, SDO 0x603 dlc 8);
 *  - while a fault is latched, every RPDO1 sent carries velocity 0;
 *  - phase, power state and fault reason stay inside their enums;
 *    is_enabled implies RUN and no fault; counters never decrease.
 */
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cia402/canopen.h"
#include "cia402/cia402.h"
#include "cia402/cia402_drive.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

enum { NODE = 3, OTHER = 5, REC = 12 };

static void require(int ok)
{
    if (!ok) {
        abort();
    }
}

/* the fake bus: checks every frame sent; the last RPDO1 velocity is kept */
static int g_fail_next;
static int g_rpdo_sent;
static int32_t g_rpdo_velocity;
static unsigned g_sent;

static hal_status_t fc_send(hal_can_t *dev, const hal_can_frame_t *f, uint32_t timeout_us)
{
    (void)dev;
    (void)timeout_us;
    if (g_fail_next) {
        g_fail_next = 0;
        return HAL_E_TIMEOUT;
    }
    require(f->flags == 0U && f->id <= HAL_CAN_STD_ID_MAX && f->dlc <= HAL_CAN_MAX_DLC);
    if (f->id == CANOPEN_COB_NMT) {
        require(f->dlc == 2U && f->data[1] == NODE);
    } else if (f->id == CANOPEN_COB_RPDO1 + NODE) {
        require(f->dlc == CIA402_PDO_DLC);
        g_rpdo_sent = 1;
        g_rpdo_velocity = (int32_t)canopen_get_u32(&f->data[2]);
    } else {
        require(f->id == CANOPEN_COB_SDO_RX + NODE && f->dlc == 8U);
    }
    g_sent++;
    return HAL_OK;
}

static hal_status_t fc_receive(hal_can_t *dev, hal_can_frame_t *f, uint32_t timeout_us)
{
    (void)dev;
    (void)f;
    (void)timeout_us;
    return HAL_E_TIMEOUT;
}

static const hal_can_ops_t fc_ops = {.send = fc_send, .receive = fc_receive};

static void check_parsers(const hal_can_frame_t *f)
{
    canopen_sdo_reply_t r;
    coslam_status_t st = canopen_sdo_parse_reply(f, &r);
    if (f->dlc != 8U) {
        require(st == COSLAM_E_DRIVE_PROTOCOL);
    } else {
        require(st == COSLAM_OK || st == COSLAM_E_DRIVE_PROTOCOL);
    }
    if (st == COSLAM_OK && r.kind == CANOPEN_SDO_REPLY_UPLOAD) {
        require(r.size >= 1U && r.size <= 4U);
        require(r.size == 4U || r.value < (1UL << (8U * r.size)));
    }
    if (st == COSLAM_OK) {
        require(r.kind >= CANOPEN_SDO_REPLY_DOWNLOAD_ACK && r.kind <= CANOPEN_SDO_REPLY_SEGMENTED);
    }
    canopen_emcy_t e;
    st = canopen_emcy_parse(f, &e);
    require(f->dlc == 8U ? st == COSLAM_OK : st == COSLAM_E_DRIVE_PROTOCOL);
    canopen_nmt_state_t ns;
    st = canopen_heartbeat_parse(f, &ns);
    require(f->dlc == 1U ? (st == COSLAM_OK && (unsigned)ns <= 0x7FU) : st == COSLAM_E_DRIVE_PROTOCOL);
    uint16_t sw = 0;
    int32_t v = 0;
    st = cia402_tpdo_parse(f, &sw, &v);
    require(f->dlc == CIA402_PDO_DLC ? st == COSLAM_OK : st == COSLAM_E_DRIVE_PROTOCOL);
    uint8_t node = 0xFF;
    const canopen_fn_t fn = canopen_classify(f, &node);
    if ((f->flags & (HAL_CAN_FLAG_EXT | HAL_CAN_FLAG_RTR)) != 0U) {
        require(fn == CANOPEN_FN_OTHER);
    }
    require(fn <= CANOPEN_FN_HEARTBEAT);
}

static void check_invariants(const cia402_drive_t *d, const cia402_drive_t *prev)
{
    require(d->phase <= CIA402_DRIVE_HALTED);
    require(d->state <= CIA402_STATE_UNKNOWN);
    const cia402_fault_info_t *fi = cia402_drive_fault(d);
    require(fi != NULL && fi->reason <= CIA402_FAULT_LEFT_ENABLED);
    if (cia402_drive_is_enabled(d)) {
        require(d->phase == CIA402_DRIVE_RUN && fi->reason == CIA402_FAULT_NONE);
    }
    require(d->rx_frames >= prev->rx_frames && d->rx_malformed >= prev->rx_malformed &&
            d->rx_unexpected >= prev->rx_unexpected && d->tx_frames >= prev->tx_frames &&
            d->emcy_count >= prev->emcy_count && d->fault_count >= prev->fault_count);
    const cia402_sdo_state_t s = cia402_drive_sdo_state(d, NULL, NULL);
    require(s <= CIA402_SDO_ERROR);
}

static const uint32_t k_base[8] = {CANOPEN_COB_HEARTBEAT + NODE, CANOPEN_COB_SDO_TX + NODE,
                                   CANOPEN_COB_TPDO1 + NODE,     CANOPEN_COB_EMCY + NODE,
                                   CANOPEN_COB_SDO_TX + OTHER,   0U,
                                   CANOPEN_COB_NMT,              CANOPEN_COB_SDO_TX + NODE};

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static cia402_drive_t d;
    static cia402_drive_t prev;
    hal_can_t can = {&fc_ops, NULL};
    const cia402_drive_config_t cfg = cia402_drive_config_default(NODE);
    require(cia402_drive_init(&d, &cfg, &can) == COSLAM_OK);
    g_fail_next = 0;
    uint64_t now_us = 1000U;
    require(cia402_drive_start(&d, now_us) == COSLAM_OK);

    for (size_t off = 0; off + REC <= size; off += REC) {
        const uint8_t *r = data + off;
        now_us += (uint64_t)r[2] * 1000U;
        /* the owner's action */
        switch (r[1] >> 4) {
        case 1: (void)cia402_drive_set_goal(&d, CIA402_GOAL_ENABLED); break;
        case 2: (void)cia402_drive_set_goal(&d, CIA402_GOAL_DISABLED); break;
        case 3: (void)cia402_drive_set_goal(&d, CIA402_GOAL_QUICK_STOP); break;
        case 4: (void)cia402_drive_set_target_velocity(&d, (int32_t)canopen_get_u32(&r[4])); break;
        case 5: (void)cia402_drive_fault_reset(&d, now_us); break;
        case 6: (void)cia402_drive_sdo_read(&d, canopen_get_u16(&r[4]), r[3], now_us); break;
        case 7:
            (void)cia402_drive_sdo_write(&d, canopen_get_u16(&r[4]), r[3], canopen_get_u32(&r[8]),
                                         (uint8_t)(r[3] % 6U), now_us);
            break;
        case 8: (void)cia402_drive_start(&d, now_us); break;
        case 9: cia402_drive_bus_error(&d, HAL_E_IO, now_us); break;
        default: break;
        }
        /* the frame */
        hal_can_frame_t f;
        memset(&f, 0, sizeof f);
        const unsigned kind = r[0] & 7U;
        f.id = kind == 5U ? ((((uint32_t)r[0] >> 3) & 7U) << 8 | r[3]) : k_base[kind];
        f.flags = (uint8_t)((kind == 7U ? HAL_CAN_FLAG_EXT : 0U) | ((r[0] & 0x40U) ? HAL_CAN_FLAG_RTR : 0U));
        f.dlc = (uint8_t)((r[1] & 0x0FU) % 9U);
        memcpy(f.data, &r[4], 8U);
        f.stamp_us = now_us;
        g_fail_next = (r[0] & 0x80U) != 0U;
        check_parsers(&f);

        uint8_t node = 0;
        const canopen_fn_t fn = canopen_classify(&f, &node);
        const int foreign = f.flags != 0U || fn == CANOPEN_FN_OTHER || node != NODE;
        memcpy(&prev, &d, sizeof d);
        const cia402_rx_t rx = cia402_drive_on_frame(&d, &f);
        if (foreign && fn != CANOPEN_FN_NMT) {
            require(rx == CIA402_RX_NOT_MINE);
            require(memcmp(&prev, &d, sizeof d) == 0);
        }
        if (rx == CIA402_RX_TPDO) {
            require(fn == CANOPEN_FN_TPDO1 && node == NODE && f.dlc == CIA402_PDO_DLC && f.flags == 0U);
        }
        check_invariants(&d, &prev);

        /* the poll */
        memcpy(&prev, &d, sizeof d);
        const int faulted = cia402_drive_fault(&d)->reason != CIA402_FAULT_NONE;
        g_rpdo_sent = 0;
        const coslam_status_t st = cia402_drive_poll(&d, now_us);
        require(st == COSLAM_OK || st == COSLAM_E_DRIVE_FAULT);
        if (faulted && g_rpdo_sent) {
            require(g_rpdo_velocity == 0);
        }
        check_invariants(&d, &prev);
    }
    if (getenv("FUZZ_TRACE") != NULL) { /* how far a seed gets */
        fprintf(stderr, "phase %d state %d fault %d enabled %d rx %u malformed %u emcy %u sent %u\n", (int)d.phase,
                (int)d.state, (int)cia402_drive_fault(&d)->reason, cia402_drive_is_enabled(&d), (unsigned)d.rx_frames,
                (unsigned)d.rx_malformed, (unsigned)d.emcy_count, g_sent);
    }
    return 0;
}
