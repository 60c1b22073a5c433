/* CANopen frames, the CiA 402 profile tables and one drive node against a
 * fake hal_can: byte-exact frames, every power-state transition, SDO abort
 * and timeout, heartbeat loss, EMCY, NMT and PDO supervision. */
#include "../slam/test_util.h"

#include <string.h>

#include "cia402/canopen.h"
#include "cia402/cia402.h"
#include "cia402/cia402_drive.h"
#include "fake_can.h"

#define NODE 5u

#define ASSERT_FRAME(f, id_, ...)                                      \
    do {                                                               \
        const uint8_t exp_[] = {__VA_ARGS__};                          \
        const hal_can_frame_t *f_ = &(f);                              \
        assert_int_equal(f_->id, (id_));                               \
        assert_int_equal(f_->flags, 0);                                \
        assert_int_equal(f_->dlc, sizeof exp_);                        \
        assert_memory_equal(f_->data, exp_, sizeof exp_);              \
    } while (0)

#define PUSH(fc, id, t, ...)                                           \
    do {                                                               \
        const uint8_t d_[] = {__VA_ARGS__};                            \
        fake_can_push((fc), (id), d_, (uint8_t)sizeof d_, (t));        \
    } while (0)

static fake_can_t g_fc;
static cia402_drive_t g_d;

/* The owner loop of one node: feed queued frames, then poll. */
static coslam_status_t run(cia402_drive_t *d, fake_can_t *fc, uint64_t now_us)
{
    hal_can_frame_t f;
    while (hal_can_receive(&fc->can, &f, 0) == HAL_OK) (void)cia402_drive_on_frame(d, &f);
    return cia402_drive_poll(d, now_us);
}

static const hal_can_frame_t *last_sent(const fake_can_t *fc)
{
    assert_true(fc->n_sent > 0);
    return &fc->sent[fc->n_sent - 1];
}

/* ------------------------------------------------------------------------ */
/* canopen.h and cia402.h                                                   */
/* ------------------------------------------------------------------------ */

static void test_canopen_frames(void **state)
{
    (void)state;
    hal_can_frame_t f;
    canopen_nmt_frame(&f, CANOPEN_NMT_START, 5);
    ASSERT_FRAME(f, 0x000, 0x01, 0x05);
    canopen_nmt_frame(&f, CANOPEN_NMT_RESET_NODE, 0);
    ASSERT_FRAME(f, 0x000, 0x81, 0x00);
    canopen_nmt_frame(&f, CANOPEN_NMT_RESET_COMM, 127);
    ASSERT_FRAME(f, 0x000, 0x82, 0x7F);

    assert_int_equal(canopen_sdo_download_frame(&f, 5, 0x6060, 0, 3, 1), COSLAM_OK);
    ASSERT_FRAME(f, 0x605, 0x2F, 0x60, 0x60, 0x00, 0x03, 0x00, 0x00, 0x00);
    assert_int_equal(canopen_sdo_download_frame(&f, 5, 0x1017, 0, 100, 2), COSLAM_OK);
    ASSERT_FRAME(f, 0x605, 0x2B, 0x17, 0x10, 0x00, 0x64, 0x00, 0x00, 0x00);
    assert_int_equal(canopen_sdo_download_frame(&f, 1, 0x2000, 7, 0xABCDEF, 3), COSLAM_OK);
    ASSERT_FRAME(f, 0x601, 0x27, 0x00, 0x20, 0x07, 0xEF, 0xCD, 0xAB, 0x00);
    assert_int_equal(canopen_sdo_download_frame(&f, 127, 0x60FF, 0, 0xFFFFFC18u, 4), COSLAM_OK);
    ASSERT_FRAME(f, 0x67F, 0x23, 0xFF, 0x60, 0x00, 0x18, 0xFC, 0xFF, 0xFF);
    assert_int_equal(canopen_sdo_download_frame(&f, 5, 0x6060, 0, 3, 0), COSLAM_E_ARG);
    assert_int_equal(canopen_sdo_download_frame(&f, 5, 0x6060, 0, 3, 5), COSLAM_E_ARG);
    assert_int_equal(canopen_sdo_download_frame(&f, 0, 0x6060, 0, 3, 1), COSLAM_E_ARG);
    assert_int_equal(canopen_sdo_download_frame(&f, 128, 0x6060, 0, 3, 1), COSLAM_E_ARG);

    assert_int_equal(canopen_sdo_upload_frame(&f, 5, 0x1018, 2), COSLAM_OK);
    ASSERT_FRAME(f, 0x605, 0x40, 0x18, 0x10, 0x02, 0x00, 0x00, 0x00, 0x00);
    assert_int_equal(canopen_sdo_abort_frame(&f, 5, 0x6041, 0, CANOPEN_SDO_ABORT_TIMEOUT), COSLAM_OK);
    ASSERT_FRAME(f, 0x605, 0x80, 0x41, 0x60, 0x00, 0x00, 0x00, 0x04, 0x05);

    assert_int_equal(cia402_rpdo_frame(&f, 3, 0x000F, -1000), COSLAM_OK);
    ASSERT_FRAME(f, 0x203, 0x0F, 0x00, 0x18, 0xFC, 0xFF, 0xFF);
    assert_int_equal(cia402_rpdo_frame(&f, 3, 0x0006, 0x12345678), COSLAM_OK);
    ASSERT_FRAME(f, 0x203, 0x06, 0x00, 0x78, 0x56, 0x34, 0x12);
}

static void test_canopen_parse(void **state)
{
    (void)state;
    hal_can_frame_t f;
    canopen_sdo_reply_t r;
    memset(&f, 0, sizeof f);
    f.id = 0x585;
    f.dlc = 8;
    const uint8_t ack[8] = {0x60, 0x17, 0x10, 0x00, 0, 0, 0, 0};
    memcpy(f.data, ack, 8);
    assert_int_equal(canopen_sdo_parse_reply(&f, &r), COSLAM_OK);
    assert_int_equal(r.kind, CANOPEN_SDO_REPLY_DOWNLOAD_ACK);
    assert_int_equal(r.index, 0x1017);
    assert_int_equal(r.subindex, 0);
    /* expedited uploads of 1..4 bytes, and "size not indicated" (0x42 -> 4) */
    const uint8_t cmds[5] = {0x4F, 0x4B, 0x47, 0x43, 0x42};
    const uint8_t sizes[5] = {1, 2, 3, 4, 4};
    const uint32_t values[5] = {0x78, 0x5678, 0x345678, 0x12345678, 0x12345678};
    for (int i = 0; i < 5; ++i) {
        const uint8_t up[8] = {cmds[i], 0x18, 0x10, 0x01, 0x78, 0x56, 0x34, 0x12};
        memcpy(f.data, up, 8);
        assert_int_equal(canopen_sdo_parse_reply(&f, &r), COSLAM_OK);
        assert_int_equal(r.kind, CANOPEN_SDO_REPLY_UPLOAD);
        assert_int_equal(r.index, 0x1018);
        assert_int_equal(r.subindex, 1);
        assert_int_equal(r.size, sizes[i]);
        assert_int_equal(r.value, values[i]);
    }
    const uint8_t seg[8] = {0x41, 0x08, 0x10, 0x00, 20, 0, 0, 0};
    memcpy(f.data, seg, 8);
    assert_int_equal(canopen_sdo_parse_reply(&f, &r), COSLAM_OK);
    assert_int_equal(r.kind, CANOPEN_SDO_REPLY_SEGMENTED);
    const uint8_t ab[8] = {0x80, 0x60, 0x60, 0x00, 0x30, 0x00, 0x09, 0x06};
    memcpy(f.data, ab, 8);
    assert_int_equal(canopen_sdo_parse_reply(&f, &r), COSLAM_OK);
    assert_int_equal(r.kind, CANOPEN_SDO_REPLY_ABORT);
    assert_int_equal(r.abort_code, CANOPEN_SDO_ABORT_VALUE_RANGE);
    f.data[0] = 0x20; /* a client command: not a valid reply */
    assert_int_equal(canopen_sdo_parse_reply(&f, &r), COSLAM_E_DRIVE_PROTOCOL);
    f.data[0] = 0x53; /* reserved bit 4 set */
    assert_int_equal(canopen_sdo_parse_reply(&f, &r), COSLAM_E_DRIVE_PROTOCOL);
    f.data[0] = 0x60;
    f.dlc = 4;
    assert_int_equal(canopen_sdo_parse_reply(&f, &r), COSLAM_E_DRIVE_PROTOCOL);

    /* EMCY and heartbeat */
    canopen_emcy_t e;
    f.id = 0x085;
    f.dlc = 8;
    const uint8_t em[8] = {0x10, 0x23, 0x01, 0xA1, 0xA2, 0xA3, 0xA4, 0xA5};
    memcpy(f.data, em, 8);
    assert_int_equal(canopen_emcy_parse(&f, &e), COSLAM_OK);
    assert_int_equal(e.error_code, 0x2310);
    assert_int_equal(e.error_register, 0x01);
    assert_int_equal(e.manufacturer[0], 0xA1);
    assert_int_equal(e.manufacturer[4], 0xA5);
    f.dlc = 7;
    assert_int_equal(canopen_emcy_parse(&f, &e), COSLAM_E_DRIVE_PROTOCOL);
    canopen_nmt_state_t st;
    f.id = 0x705;
    f.dlc = 1;
    f.data[0] = 0x85; /* toggle bit set, operational */
    assert_int_equal(canopen_heartbeat_parse(&f, &st), COSLAM_OK);
    assert_int_equal(st, CANOPEN_NMT_STATE_OPERATIONAL);
    f.dlc = 2;
    assert_int_equal(canopen_heartbeat_parse(&f, &st), COSLAM_E_DRIVE_PROTOCOL);
    /* a producer's heartbeat: the master's, node 127, operational */
    assert_int_equal(canopen_heartbeat_frame(&f, 127, CANOPEN_NMT_STATE_OPERATIONAL), COSLAM_OK);
    ASSERT_FRAME(f, 0x77F, 0x05);
    assert_int_equal(canopen_heartbeat_frame(&f, 0, CANOPEN_NMT_STATE_OPERATIONAL), COSLAM_E_ARG);
    assert_int_equal(canopen_heartbeat_frame(&f, 128, CANOPEN_NMT_STATE_OPERATIONAL), COSLAM_E_ARG);

    /* TPDO with a negative velocity */
    uint16_t sw;
    int32_t vel;
    f.id = 0x185;
    f.dlc = 6;
    const uint8_t tp[6] = {0x37, 0x16, 0x18, 0xFC, 0xFF, 0xFF};
    memcpy(f.data, tp, 6);
    assert_int_equal(cia402_tpdo_parse(&f, &sw, &vel), COSLAM_OK);
    assert_int_equal(sw, 0x1637);
    assert_int_equal(vel, -1000);
    const uint8_t tmin[6] = {0, 0, 0x00, 0x00, 0x00, 0x80};
    memcpy(f.data, tmin, 6);
    assert_int_equal(cia402_tpdo_parse(&f, &sw, &vel), COSLAM_OK);
    assert_true(vel == INT32_MIN);
    f.dlc = 8;
    assert_int_equal(cia402_tpdo_parse(&f, &sw, &vel), COSLAM_E_DRIVE_PROTOCOL);
}

static void test_canopen_classify(void **state)
{
    (void)state;
    hal_can_frame_t f;
    memset(&f, 0, sizeof f);
    uint8_t node = 99;
    const struct {
        uint32_t id;
        canopen_fn_t fn;
        uint8_t node;
    } cases[] = {
        {0x000, CANOPEN_FN_NMT, 0},       {0x080, CANOPEN_FN_OTHER, 0}, /* SYNC */
        {0x081, CANOPEN_FN_EMCY, 1},      {0x0FF, CANOPEN_FN_EMCY, 127},
        {0x185, CANOPEN_FN_TPDO1, 5},     {0x205, CANOPEN_FN_RPDO1, 5},
        {0x285, CANOPEN_FN_OTHER, 0},     {0x585, CANOPEN_FN_SDO_TX, 5},
        {0x605, CANOPEN_FN_SDO_RX, 5},    {0x705, CANOPEN_FN_HEARTBEAT, 5},
        {0x100, CANOPEN_FN_OTHER, 0},     {0x77F, CANOPEN_FN_HEARTBEAT, 127},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        f.id = cases[i].id;
        assert_int_equal(canopen_classify(&f, &node), cases[i].fn);
        assert_int_equal(node, cases[i].node);
    }
    f.id = 0x185;
    f.flags = HAL_CAN_FLAG_EXT;
    assert_int_equal(canopen_classify(&f, &node), CANOPEN_FN_OTHER);
    f.flags = HAL_CAN_FLAG_RTR;
    assert_int_equal(canopen_classify(&f, &node), CANOPEN_FN_OTHER);
}

static void test_statusword_decoding(void **state)
{
    (void)state;
    const struct {
        uint16_t sw;
        cia402_state_t st;
    } cases[] = {
        {0x0000, CIA402_STATE_NOT_READY},
        {0x0020, CIA402_STATE_NOT_READY},          /* bit 5 is don't care here */
        {0x0040, CIA402_STATE_SWITCH_ON_DISABLED},
        {0x0260, CIA402_STATE_SWITCH_ON_DISABLED},
        {0x0021, CIA402_STATE_READY_TO_SWITCH_ON},
        {0x0231, CIA402_STATE_READY_TO_SWITCH_ON}, /* voltage + remote bits */
        {0x0023, CIA402_STATE_SWITCHED_ON},
        {0x0233, CIA402_STATE_SWITCHED_ON},
        {0x0027, CIA402_STATE_OPERATION_ENABLED},
        {0x1637, CIA402_STATE_OPERATION_ENABLED},
        {0x0007, CIA402_STATE_QUICK_STOP_ACTIVE},
        {0x0217, CIA402_STATE_QUICK_STOP_ACTIVE},
        {0x000F, CIA402_STATE_FAULT_REACTION_ACTIVE},
        {0x002F, CIA402_STATE_FAULT_REACTION_ACTIVE},
        {0x0008, CIA402_STATE_FAULT},
        {0x0228, CIA402_STATE_FAULT},
        {0x0001, CIA402_STATE_UNKNOWN},
        {0x0048, CIA402_STATE_UNKNOWN},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        if (cia402_state_from_statusword(cases[i].sw) != cases[i].st) {
            fail_msg("statusword 0x%04x: got %s want %s", cases[i].sw,
                     cia402_state_str(cia402_state_from_statusword(cases[i].sw)), cia402_state_str(cases[i].st));
        }
    }
}

static void test_controlword_table(void **state)
{
    (void)state;
    /* rows: state; columns: goal DISABLED, ENABLED, QUICK_STOP */
    const struct {
        cia402_state_t st;
        uint16_t cw[3];
    } rows[] = {
        {CIA402_STATE_NOT_READY, {0x00, 0x00, 0x00}},
        {CIA402_STATE_SWITCH_ON_DISABLED, {0x00, 0x06, 0x02}},
        {CIA402_STATE_READY_TO_SWITCH_ON, {0x00, 0x07, 0x02}},
        {CIA402_STATE_SWITCHED_ON, {0x00, 0x0F, 0x02}},
        {CIA402_STATE_OPERATION_ENABLED, {0x00, 0x0F, 0x02}},
        {CIA402_STATE_QUICK_STOP_ACTIVE, {0x00, 0x00, 0x02}},
        {CIA402_STATE_FAULT_REACTION_ACTIVE, {0x00, 0x00, 0x00}},
        {CIA402_STATE_FAULT, {0x00, 0x00, 0x00}},
        {CIA402_STATE_UNKNOWN, {0x00, 0x00, 0x00}},
    };
    const cia402_goal_t goals[3] = {CIA402_GOAL_DISABLED, CIA402_GOAL_ENABLED, CIA402_GOAL_QUICK_STOP};
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; ++i) {
        for (int g = 0; g < 3; ++g) {
            const uint16_t cw = cia402_controlword_for(rows[i].st, goals[g]);
            if (cw != rows[i].cw[g]) {
                fail_msg("%s goal %d: cw 0x%02x want 0x%02x", cia402_state_str(rows[i].st), g, cw, rows[i].cw[g]);
            }
        }
    }
}

/* ------------------------------------------------------------------------ */
/* one drive                                                                */
/* ------------------------------------------------------------------------ */

static int setup(void **state)
{
    (void)state;
    fake_can_init(&g_fc);
    const cia402_drive_config_t cfg = cia402_drive_config_default(NODE);
    assert_int_equal(cia402_drive_init(&g_d, &cfg, &g_fc.can), COSLAM_OK);
    return 0;
}

/* Bring-up with every request checked byte for byte; returns the time. */
static uint64_t bring_up_checked(void)
{
    fake_can_t *fc = &g_fc;
    cia402_drive_t *d = &g_d;
    uint64_t t = 1000;
    assert_int_equal(cia402_drive_start(d, t), COSLAM_OK);
    assert_int_equal(fc->n_sent, 1);
    ASSERT_FRAME(fc->sent[0], 0x000, 0x81, NODE);
    assert_int_equal(d->phase, CIA402_DRIVE_BOOT);
    /* a heartbeat from before the reset does not count as the boot-up */
    PUSH(fc, 0x700 + NODE, t + 50, 0x7F);
    assert_int_equal(run(d, fc, t += 100), COSLAM_OK);
    assert_int_equal(d->phase, CIA402_DRIVE_BOOT);
    PUSH(fc, 0x700 + NODE, t + 50, 0x00);
    assert_int_equal(run(d, fc, t += 100), COSLAM_OK);
    assert_int_equal(d->phase, CIA402_DRIVE_CONFIG);
    assert_int_equal(fc->n_sent, 2);
    ASSERT_FRAME(fc->sent[1], 0x600 + NODE, 0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0);
    PUSH(fc, 0x580 + NODE, t + 50, 0x43, 0x18, 0x10, 0x01, 0x78, 0x56, 0x34, 0x12);
    run(d, fc, t += 100);
    ASSERT_FRAME(fc->sent[2], 0x600 + NODE, 0x40, 0x18, 0x10, 0x02, 0, 0, 0, 0);
    PUSH(fc, 0x580 + NODE, t + 50, 0x43, 0x18, 0x10, 0x02, 0x02, 0x04, 0x00, 0x00);
    run(d, fc, t += 100);
    ASSERT_FRAME(fc->sent[3], 0x600 + NODE, 0x2B, 0x17, 0x10, 0x00, 0x64, 0x00, 0, 0);
    PUSH(fc, 0x580 + NODE, t + 50, 0x60, 0x17, 0x10, 0x00, 0, 0, 0, 0);
    run(d, fc, t += 100);
    /* the drive-side watchdog: consume node 127's heartbeat, 200 ms (0x007F00C8) ... */
    ASSERT_FRAME(fc->sent[4], 0x600 + NODE, 0x23, 0x16, 0x10, 0x01, 0xC8, 0x00, 0x7F, 0x00);
    PUSH(fc, 0x580 + NODE, t + 50, 0x60, 0x16, 0x10, 0x01, 0, 0, 0, 0);
    run(d, fc, t += 100);
    /* ... and quick stop when it stays away (0x6007 = 3, i16) */
    ASSERT_FRAME(fc->sent[5], 0x600 + NODE, 0x2B, 0x07, 0x60, 0x00, 0x03, 0x00, 0, 0);
    PUSH(fc, 0x580 + NODE, t + 50, 0x60, 0x07, 0x60, 0x00, 0, 0, 0, 0);
    run(d, fc, t += 100);
    ASSERT_FRAME(fc->sent[6], 0x600 + NODE, 0x2F, 0x60, 0x60, 0x00, 0x03, 0, 0, 0);
    PUSH(fc, 0x580 + NODE, t + 50, 0x60, 0x60, 0x60, 0x00, 0, 0, 0, 0);
    run(d, fc, t += 100);
    ASSERT_FRAME(fc->sent[7], 0x600 + NODE, 0x40, 0x61, 0x60, 0x00, 0, 0, 0, 0);
    PUSH(fc, 0x580 + NODE, t + 50, 0x4F, 0x61, 0x60, 0x00, 0x03, 0, 0, 0);
    run(d, fc, t += 100);
    ASSERT_FRAME(fc->sent[8], 0x600 + NODE, 0x40, 0x41, 0x60, 0x00, 0, 0, 0, 0);
    PUSH(fc, 0x580 + NODE, t + 50, 0x4B, 0x41, 0x60, 0x00, 0x40, 0x02, 0, 0);
    PUSH(fc, 0x700 + NODE, t + 60, 0x7F);
    run(d, fc, t += 100);
    assert_int_equal(fc->n_sent, 10);
    ASSERT_FRAME(fc->sent[9], 0x000, 0x01, NODE);
    assert_int_equal(d->phase, CIA402_DRIVE_RUN);
    assert_int_equal(d->vendor_id, 0x12345678);
    assert_int_equal(d->product_code, 0x402);
    assert_int_equal(d->state, CIA402_STATE_SWITCH_ON_DISABLED);
    /* operational heartbeat and a first TPDO */
    PUSH(fc, 0x700 + NODE, t + 50, 0x05);
    PUSH(fc, 0x180 + NODE, t + 60, 0x40, 0x02, 0, 0, 0, 0);
    assert_int_equal(run(d, fc, t += 100), COSLAM_OK);
    assert_int_equal(fc->n_sent, 11);
    ASSERT_FRAME(fc->sent[10], 0x200 + NODE, 0x00, 0x00, 0, 0, 0, 0);
    assert_int_equal(d->nmt_confirmed, 1);
    assert_int_equal(d->fault.reason, CIA402_FAULT_NONE);
    return t;
}

/* Drive the power state machine to OPERATION_ENABLED; returns the time. */
static uint64_t enable_checked(uint64_t t)
{
    fake_can_t *fc = &g_fc;
    cia402_drive_t *d = &g_d;
    assert_int_equal(cia402_drive_set_goal(d, CIA402_GOAL_ENABLED), COSLAM_OK);
    assert_int_equal(cia402_drive_set_target_velocity(d, 1234), COSLAM_OK);
    run(d, fc, t += 1000);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x06, 0x00, 0, 0, 0, 0); /* shutdown, velocity held at 0 */
    PUSH(fc, 0x180 + NODE, t + 100, 0x21, 0x02, 0, 0, 0, 0);
    run(d, fc, t += 1000);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x07, 0x00, 0, 0, 0, 0); /* switch on */
    PUSH(fc, 0x180 + NODE, t + 100, 0x33, 0x02, 0, 0, 0, 0);
    run(d, fc, t += 1000);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x0F, 0x00, 0, 0, 0, 0); /* enable operation */
    assert_false(cia402_drive_is_enabled(d));
    PUSH(fc, 0x180 + NODE, t + 100, 0x37, 0x02, 0, 0, 0, 0);
    run(d, fc, t += 1000);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x0F, 0x00, 0xD2, 0x04, 0, 0); /* and now the velocity */
    assert_true(cia402_drive_is_enabled(d));
    return t;
}

static void test_bring_up_and_enable(void **state)
{
    (void)state;
    uint64_t t = bring_up_checked();
    t = enable_checked(t);
    fake_can_t *fc = &g_fc;
    cia402_drive_t *d = &g_d;
    /* a new velocity goes out at once, negative values little-endian */
    cia402_drive_set_target_velocity(d, -1000);
    const size_t n = fc->n_sent;
    run(d, fc, t += 100);
    assert_int_equal(fc->n_sent, n + 1);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x0F, 0x00, 0x18, 0xFC, 0xFF, 0xFF);
    /* nothing new before the refresh period, then the same RPDO again */
    run(d, fc, t += 5000);
    assert_int_equal(fc->n_sent, n + 1);
    PUSH(fc, 0x700 + NODE, t, 0x05);
    run(d, fc, t += 5000);
    assert_int_equal(fc->n_sent, n + 2);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x0F, 0x00, 0x18, 0xFC, 0xFF, 0xFF);
    assert_int_equal(d->fault.reason, CIA402_FAULT_NONE);
}

static void test_disable_and_quick_stop_transitions(void **state)
{
    (void)state;
    uint64_t t = enable_checked(bring_up_checked());
    fake_can_t *fc = &g_fc;
    cia402_drive_t *d = &g_d;
    /* OPERATION_ENABLED --quick stop--> QUICK_STOP_ACTIVE --> SWITCH_ON_DISABLED */
    cia402_drive_set_goal(d, CIA402_GOAL_QUICK_STOP);
    PUSH(fc, 0x700 + NODE, t, 0x05);
    run(d, fc, t += 1000);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x02, 0x00, 0, 0, 0, 0);
    PUSH(fc, 0x180 + NODE, t + 100, 0x17, 0x02, 0, 0, 0, 0);
    run(d, fc, t += 1000);
    assert_int_equal(d->state, CIA402_STATE_QUICK_STOP_ACTIVE);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x02, 0x00, 0, 0, 0, 0);
    PUSH(fc, 0x180 + NODE, t + 100, 0x40, 0x02, 0, 0, 0, 0);
    run(d, fc, t += 1000);
    assert_int_equal(d->state, CIA402_STATE_SWITCH_ON_DISABLED);
    /* back up to enabled, then disable voltage from OPERATION_ENABLED */
    t = enable_checked(t);
    cia402_drive_set_goal(d, CIA402_GOAL_DISABLED);
    PUSH(fc, 0x700 + NODE, t, 0x05);
    run(d, fc, t += 1000);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x00, 0x00, 0, 0, 0, 0);
    PUSH(fc, 0x180 + NODE, t + 100, 0x40, 0x02, 0, 0, 0, 0);
    run(d, fc, t += 1000);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x00, 0x00, 0, 0, 0, 0);
    /* a drive that drops to NOT_READY gets "disable voltage" while enabling */
    cia402_drive_set_goal(d, CIA402_GOAL_ENABLED);
    PUSH(fc, 0x180 + NODE, t + 100, 0x00, 0x02, 0, 0, 0, 0);
    PUSH(fc, 0x700 + NODE, t + 100, 0x05);
    const size_t n = fc->n_sent;
    run(d, fc, t += 10000);
    assert_int_equal(fc->n_sent, n + 1);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x00, 0x00, 0, 0, 0, 0);
    assert_int_equal(d->state, CIA402_STATE_NOT_READY);
    assert_int_equal(d->fault.reason, CIA402_FAULT_NONE);
}

static void test_emcy_fault_and_fault_reset(void **state)
{
    (void)state;
    uint64_t t = enable_checked(bring_up_checked());
    fake_can_t *fc = &g_fc;
    cia402_drive_t *d = &g_d;
    /* EMCY 0x2310 (continuous over-current): latched, quick stop at once */
    PUSH(fc, 0x080 + NODE, t + 10, 0x10, 0x23, 0x01, 0, 0, 0, 0, 0);
    PUSH(fc, 0x700 + NODE, t + 20, 0x05);
    assert_int_equal(run(d, fc, t += 100), COSLAM_E_DRIVE_FAULT);
    assert_int_equal(d->fault.reason, CIA402_FAULT_EMCY);
    assert_int_equal(d->fault.emcy_code, 0x2310);
    assert_int_equal(d->fault.emcy_register, 0x01);
    assert_int_equal(d->fault.stamp_us, t - 90);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x02, 0x00, 0, 0, 0, 0);
    assert_false(cia402_drive_is_enabled(d));
    /* the drive passes through FAULT_REACTION_ACTIVE into FAULT: bit 7 low */
    PUSH(fc, 0x180 + NODE, t + 10, 0x0F, 0x02, 0, 0, 0, 0);
    run(d, fc, t += 100);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x00, 0x00, 0, 0, 0, 0);
    PUSH(fc, 0x180 + NODE, t + 10, 0x08, 0x02, 0, 0, 0, 0);
    run(d, fc, t += 100);
    assert_int_equal(d->state, CIA402_STATE_FAULT);
    assert_int_equal(d->fault.reason, CIA402_FAULT_EMCY); /* first cause kept */
    assert_int_equal(d->fault.statusword, 0x0208);
    /* without a reset request the drive stays in FAULT with 0x00 */
    run(d, fc, t += 20000);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x00, 0x00, 0, 0, 0, 0);
    /* fault reset: rising edge of bit 7, held until the drive leaves FAULT */
    PUSH(fc, 0x700 + NODE, t, 0x05);
    assert_int_equal(cia402_drive_fault_reset(d, t), COSLAM_OK);
    assert_int_equal(run(d, fc, t += 100), COSLAM_E_DRIVE_FAULT);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x80, 0x00, 0, 0, 0, 0);
    PUSH(fc, 0x180 + NODE, t + 10, 0x08, 0x02, 0, 0, 0, 0);
    run(d, fc, t += 20000);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x80, 0x00, 0, 0, 0, 0);
    PUSH(fc, 0x180 + NODE, t + 10, 0x40, 0x02, 0, 0, 0, 0);
    PUSH(fc, 0x080 + NODE, t + 20, 0x00, 0x00, 0x00, 0, 0, 0, 0, 0); /* "error reset" EMCY */
    PUSH(fc, 0x700 + NODE, t + 30, 0x05);
    assert_int_equal(run(d, fc, t += 100), COSLAM_OK);
    assert_int_equal(d->fault.reason, CIA402_FAULT_NONE);
    assert_int_equal(d->emcy_count, 2);
    assert_int_equal(d->goal, CIA402_GOAL_DISABLED); /* re-enable is explicit */
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x00, 0x00, 0, 0, 0, 0);
    enable_checked(t);
}

static void test_device_fault_without_emcy(void **state)
{
    (void)state;
    uint64_t t = enable_checked(bring_up_checked());
    fake_can_t *fc = &g_fc;
    cia402_drive_t *d = &g_d;
    PUSH(fc, 0x180 + NODE, t + 10, 0x0F, 0x02, 0, 0, 0, 0); /* FAULT_REACTION_ACTIVE */
    assert_int_equal(run(d, fc, t += 100), COSLAM_E_DRIVE_FAULT);
    assert_int_equal(d->fault.reason, CIA402_FAULT_DEVICE);
    assert_int_equal(d->fault.statusword, 0x020F);
    assert_int_equal(d->fault.emcy_code, 0);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x00, 0x00, 0, 0, 0, 0);
    /* reset requested while still reacting: wait (0x00), then edge once in FAULT */
    cia402_drive_fault_reset(d, t);
    run(d, fc, t += 100);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x00, 0x00, 0, 0, 0, 0);
    PUSH(fc, 0x180 + NODE, t + 10, 0x08, 0x02, 0, 0, 0, 0);
    run(d, fc, t += 100);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x80, 0x00, 0, 0, 0, 0);
    /* the drive stays in FAULT (cause persists); a second reset request
     * needs a new edge: bit 7 low first, then high again */
    PUSH(fc, 0x180 + NODE, t + 10, 0x08, 0x02, 0, 0, 0, 0);
    PUSH(fc, 0x700 + NODE, t + 10, 0x05);
    run(d, fc, t += 100);
    cia402_drive_fault_reset(d, t);
    const size_t n = fc->n_sent;
    run(d, fc, t += 100);
    run(d, fc, t += 100);
    assert_int_equal(fc->n_sent, n + 2);
    ASSERT_FRAME(fc->sent[n], 0x200 + NODE, 0x00, 0x00, 0, 0, 0, 0);
    ASSERT_FRAME(fc->sent[n + 1], 0x200 + NODE, 0x80, 0x00, 0, 0, 0, 0);
    assert_int_equal(d->fault.reason, CIA402_FAULT_DEVICE);
    PUSH(fc, 0x180 + NODE, t + 10, 0x40, 0x02, 0, 0, 0, 0);
    PUSH(fc, 0x700 + NODE, t + 10, 0x05);
    assert_int_equal(run(d, fc, t += 100), COSLAM_OK);
}

/* Start the bring-up at t and answer the boot-up, both identity reads and
 * the 0x1017 write, 10 ms apart; returns the time. */
static uint64_t config_to_heartbeat(cia402_drive_t *d, fake_can_t *fc, uint64_t t)
{
    cia402_drive_start(d, t);
    PUSH(fc, 0x700 + NODE, t + 5, 0x00);
    run(d, fc, t += 10);
    PUSH(fc, 0x580 + NODE, t + 5, 0x43, 0x18, 0x10, 0x01, 1, 0, 0, 0);
    run(d, fc, t += 10);
    PUSH(fc, 0x580 + NODE, t + 5, 0x43, 0x18, 0x10, 0x02, 2, 0, 0, 0);
    run(d, fc, t += 10);
    PUSH(fc, 0x580 + NODE, t + 5, 0x60, 0x17, 0x10, 0x00, 0, 0, 0, 0);
    run(d, fc, t += 10);
    return t;
}

/* ... and the two watchdog writes (0x1016:1, 0x6007) */
static uint64_t config_to_watchdog(cia402_drive_t *d, fake_can_t *fc, uint64_t t)
{
    t = config_to_heartbeat(d, fc, t);
    PUSH(fc, 0x580 + NODE, t + 5, 0x60, 0x16, 0x10, 0x01, 0, 0, 0, 0);
    run(d, fc, t += 10);
    PUSH(fc, 0x580 + NODE, t + 5, 0x60, 0x07, 0x60, 0x00, 0, 0, 0, 0);
    run(d, fc, t += 10);
    return t;
}

static void test_sdo_abort_during_config(void **state)
{
    (void)state;
    fake_can_t *fc = &g_fc;
    cia402_drive_t *d = &g_d;
    /* answer identity, heartbeat and watchdog, then abort the mode write */
    uint64_t t = config_to_watchdog(d, fc, 0);
    ASSERT_FRAME(*last_sent(fc), 0x600 + NODE, 0x2F, 0x60, 0x60, 0x00, 0x03, 0, 0, 0);
    PUSH(fc, 0x580 + NODE, t + 5, 0x80, 0x60, 0x60, 0x00, 0x30, 0x00, 0x09, 0x06);
    assert_int_equal(run(d, fc, t += 10), COSLAM_E_DRIVE_FAULT);
    assert_int_equal(d->fault.reason, CIA402_FAULT_SDO_ABORT);
    assert_int_equal(d->fault.sdo_abort_code, 0x06090030u);
    assert_int_equal(d->fault.sdo_index, 0x6060);
    assert_int_equal(d->phase, CIA402_DRIVE_HALTED);
    /* halted: nothing more is sent, however long we wait */
    const size_t n = fc->n_sent;
    for (int i = 0; i < 100; ++i) run(d, fc, t += 10000);
    assert_int_equal(fc->n_sent, n);
    /* fault reset restarts the bring-up with an NMT reset */
    cia402_drive_fault_reset(d, t);
    assert_int_equal(d->phase, CIA402_DRIVE_BOOT);
    ASSERT_FRAME(*last_sent(fc), 0x000, 0x81, NODE);
    assert_int_equal(d->fault.reason, CIA402_FAULT_NONE);
}

static void test_sdo_timeout_and_boot_timeout(void **state)
{
    (void)state;
    fake_can_t *fc = &g_fc;
    cia402_drive_t *d = &g_d;
    uint64_t t = 0;
    cia402_drive_start(d, t);
    /* boot-up times out after exactly boot_timeout_us */
    assert_int_equal(run(d, fc, t = d->cfg.boot_timeout_us - 1), COSLAM_OK);
    assert_int_equal(run(d, fc, t = d->cfg.boot_timeout_us), COSLAM_E_DRIVE_FAULT);
    assert_int_equal(d->fault.reason, CIA402_FAULT_BOOT_TIMEOUT);
    assert_int_equal(d->phase, CIA402_DRIVE_HALTED);

    /* SDO: the first request goes unanswered; abort 0x05040000 after the timeout */
    cia402_drive_start(d, t);
    PUSH(fc, 0x700 + NODE, t + 5, 0x00);
    run(d, fc, t += 10);
    ASSERT_FRAME(*last_sent(fc), 0x600 + NODE, 0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0);
    const uint64_t sent_at = t;
    const size_t n = fc->n_sent;
    assert_int_equal(run(d, fc, sent_at + d->cfg.sdo_timeout_us - 1), COSLAM_OK);
    assert_int_equal(fc->n_sent, n);
    run(d, fc, sent_at + d->cfg.sdo_timeout_us);
    assert_int_equal(fc->n_sent, n + 1);
    ASSERT_FRAME(*last_sent(fc), 0x600 + NODE, 0x80, 0x18, 0x10, 0x01, 0x00, 0x00, 0x04, 0x05);
    assert_int_equal(run(d, fc, sent_at + d->cfg.sdo_timeout_us + 1), COSLAM_E_DRIVE_FAULT);
    assert_int_equal(d->fault.reason, CIA402_FAULT_SDO_TIMEOUT);
    /* a late reply changes nothing */
    PUSH(fc, 0x580 + NODE, t, 0x43, 0x18, 0x10, 0x01, 1, 0, 0, 0);
    run(d, fc, t += 100000);
    assert_int_equal(d->fault.reason, CIA402_FAULT_SDO_TIMEOUT);
    assert_int_equal(d->rx_unexpected, 1);
}

static void test_config_rejects_bad_replies(void **state)
{
    (void)state;
    fake_can_t *fc = &g_fc;
    cia402_drive_t *d = &g_d;
    uint64_t t = 0;
    /* a reply for another object: the driver aborts and halts */
    cia402_drive_start(d, t);
    PUSH(fc, 0x700 + NODE, t + 5, 0x00);
    run(d, fc, t += 10);
    PUSH(fc, 0x580 + NODE, t + 5, 0x43, 0x18, 0x10, 0x02, 1, 0, 0, 0);
    assert_int_equal(run(d, fc, t += 10), COSLAM_E_DRIVE_FAULT);
    assert_int_equal(d->fault.reason, CIA402_FAULT_CONFIG);
    ASSERT_FRAME(*last_sent(fc), 0x600 + NODE, 0x80, 0x18, 0x10, 0x01, 0x00, 0x00, 0x00, 0x08);
    /* a segmented upload answer is refused with "command not valid" */
    cia402_drive_start(d, t);
    PUSH(fc, 0x700 + NODE, t + 5, 0x00);
    run(d, fc, t += 10);
    PUSH(fc, 0x580 + NODE, t + 5, 0x41, 0x18, 0x10, 0x01, 20, 0, 0, 0);
    assert_int_equal(run(d, fc, t += 10), COSLAM_E_DRIVE_FAULT);
    assert_int_equal(d->fault.reason, CIA402_FAULT_CONFIG);
    ASSERT_FRAME(*last_sent(fc), 0x600 + NODE, 0x80, 0x18, 0x10, 0x01, 0x01, 0x00, 0x04, 0x05);
    /* a drive that does not take profile velocity mode */
    t = config_to_watchdog(d, fc, t);
    PUSH(fc, 0x580 + NODE, t + 5, 0x60, 0x60, 0x60, 0x00, 0, 0, 0, 0);
    run(d, fc, t += 10);
    PUSH(fc, 0x580 + NODE, t + 5, 0x4F, 0x61, 0x60, 0x00, 0x02, 0, 0, 0); /* mode 2 (vl) */
    assert_int_equal(run(d, fc, t += 10), COSLAM_E_DRIVE_FAULT);
    assert_int_equal(d->fault.reason, CIA402_FAULT_CONFIG);
    assert_int_equal(d->fault.sdo_index, 0x6061); /* the mode check, not a mismatched reply */
    assert_int_equal(d->phase, CIA402_DRIVE_HALTED);
}

static void test_heartbeat_loss(void **state)
{
    (void)state;
    uint64_t t = enable_checked(bring_up_checked());
    fake_can_t *fc = &g_fc;
    cia402_drive_t *d = &g_d;
    const uint64_t hb = t;
    PUSH(fc, 0x700 + NODE, hb, 0x05);
    /* TPDOs keep coming, heartbeats stop */
    for (uint64_t k = 1; k <= 24; ++k) {
        PUSH(fc, 0x180 + NODE, hb + k * 10000, 0x37, 0x02, 0xD2, 0x04, 0, 0);
        assert_int_equal(run(d, fc, hb + k * 10000), COSLAM_OK);
    }
    assert_int_equal(run(d, fc, hb + d->cfg.heartbeat_timeout_us), COSLAM_OK);
    assert_int_equal(run(d, fc, hb + d->cfg.heartbeat_timeout_us + 1), COSLAM_E_DRIVE_FAULT);
    assert_int_equal(d->fault.reason, CIA402_FAULT_HEARTBEAT);
    ASSERT_FRAME(*last_sent(fc), 0x200 + NODE, 0x02, 0x00, 0, 0, 0, 0); /* quick stop, velocity 0 */
    /* the reset of a lost node is a new bring-up */
    t = hb + d->cfg.heartbeat_timeout_us + 100;
    cia402_drive_fault_reset(d, t);
    ASSERT_FRAME(*last_sent(fc), 0x000, 0x81, NODE);
    assert_int_equal(d->phase, CIA402_DRIVE_BOOT);
}

static void test_nmt_and_pdo_supervision(void **state)
{
    (void)state;
    fake_can_t *fc = &g_fc;
    cia402_drive_t *d = &g_d;
    /* a node that reboots while running */
    uint64_t t = bring_up_checked();
    PUSH(fc, 0x700 + NODE, t + 10, 0x00);
    assert_int_equal(run(d, fc, t += 100), COSLAM_E_DRIVE_FAULT);
    assert_int_equal(d->fault.reason, CIA402_FAULT_NMT);
    /* a node that drops to pre-operational */
    setup(NULL);
    t = bring_up_checked();
    PUSH(fc, 0x700 + NODE, t + 10, 0x7F);
    assert_int_equal(run(d, fc, t += 100), COSLAM_E_DRIVE_FAULT);
    assert_int_equal(d->fault.reason, CIA402_FAULT_NMT);
    /* TPDOs stop while heartbeats continue */
    setup(NULL);
    t = bring_up_checked();
    const uint64_t last_pdo = t - 100 + 60; /* the TPDO in bring_up_checked */
    for (uint64_t k = 1; k <= 9; ++k) {
        PUSH(fc, 0x700 + NODE, t + k * 10000, 0x05);
        assert_int_equal(run(d, fc, t + k * 10000), COSLAM_OK);
    }
    assert_int_equal(run(d, fc, last_pdo + d->cfg.pdo_timeout_us), COSLAM_OK);
    assert_int_equal(run(d, fc, last_pdo + d->cfg.pdo_timeout_us + 1), COSLAM_E_DRIVE_FAULT);
    assert_int_equal(d->fault.reason, CIA402_FAULT_PDO_TIMEOUT);
    /* NMT start never confirmed by an operational heartbeat */
    setup(NULL);
    t = 0;
    cia402_drive_start(d, t);
    PUSH(fc, 0x700 + NODE, t, 0x00);
    run(d, fc, t += 10);
    const uint8_t cmd[8] = {0x43, 0x43, 0x60, 0x60, 0x60, 0x60, 0x4F, 0x4B};
    const uint16_t idx[8] = {0x1018, 0x1018, 0x1017, 0x1016, 0x6007, 0x6060, 0x6061, 0x6041};
    const uint8_t sub[8] = {1, 2, 0, 1, 0, 0, 0, 0};
    const uint8_t val[8] = {1, 2, 0, 0, 0, 0, 3, 0x40};
    for (int i = 0; i < 8; ++i) {
        const uint8_t rep[8] = {cmd[i], (uint8_t)(idx[i] & 0xFF), (uint8_t)(idx[i] >> 8), sub[i], val[i], 0, 0, 0};
        fake_can_push(fc, 0x580 + NODE, rep, 8, t);
        run(d, fc, t += 10);
    }
    assert_int_equal(d->phase, CIA402_DRIVE_RUN);
    const uint64_t run_at = t;
    for (uint64_t k = 1; k <= 24; ++k) {
        PUSH(fc, 0x700 + NODE, run_at + k * 10000, 0x7F); /* still pre-operational */
        PUSH(fc, 0x180 + NODE, run_at + k * 10000, 0x40, 0x02, 0, 0, 0, 0);
        assert_int_equal(run(d, fc, run_at + k * 10000), COSLAM_OK);
    }
    run(d, fc, run_at + d->cfg.heartbeat_timeout_us + 1);
    assert_int_equal(d->fault.reason, CIA402_FAULT_NMT);
}

/* The drive-side watchdog's configuration: checked, skipped when off,
 * refused by a drive without the objects (halted, the object named), and a
 * fired watchdog (EMCY 0x8130: the drive left OPERATIONAL) is cleared by a
 * new bring-up, not by the in-place CiA 402 fault reset. */
static void test_watchdog_config(void **state)
{
    (void)state;
    fake_can_t *fc = &g_fc;
    cia402_drive_t *d = &g_d;
    cia402_drive_config_t c = cia402_drive_config_default(NODE);
    assert_int_equal(cia402_drive_config_check(&c), COSLAM_OK);
    c.master_node_id = NODE; /* its own id */
    assert_int_equal(cia402_drive_config_check(&c), COSLAM_E_ARG);
    c.master_node_id = 128;
    assert_int_equal(cia402_drive_config_check(&c), COSLAM_E_ARG);
    c = cia402_drive_config_default(NODE);
    c.master_timeout_ms = 0;
    assert_int_equal(cia402_drive_config_check(&c), COSLAM_E_ARG);
    c = cia402_drive_config_default(NODE);
    c.master_loss_action = 0; /* "no action" is no watchdog: say master_node_id = 0 */
    assert_int_equal(cia402_drive_config_check(&c), COSLAM_E_ARG);
    c.master_loss_action = 4;
    assert_int_equal(cia402_drive_config_check(&c), COSLAM_E_ARG);
    c.master_node_id = 0; /* off: the other two are not looked at */
    c.master_timeout_ms = 0;
    assert_int_equal(cia402_drive_config_check(&c), COSLAM_OK);

    /* off: the bring-up goes from 0x1017 to the mode write */
    fake_can_init(fc);
    assert_int_equal(cia402_drive_init(d, &c, &fc->can), COSLAM_OK);
    uint64_t t = 0;
    t = config_to_heartbeat(d, fc, t);
    ASSERT_FRAME(*last_sent(fc), 0x600 + NODE, 0x2F, 0x60, 0x60, 0x00, 0x03, 0, 0, 0);

    /* on, and the drive has no 0x1016: halted on SDO_ABORT naming it */
    setup(NULL);
    t = 0;
    t = config_to_heartbeat(d, fc, t);
    PUSH(fc, 0x580 + NODE, t + 5, 0x80, 0x16, 0x10, 0x01, 0x00, 0x00, 0x02, 0x06); /* no object */
    assert_int_equal(run(d, fc, t += 10), COSLAM_E_DRIVE_FAULT);
    assert_int_equal(d->fault.reason, CIA402_FAULT_SDO_ABORT);
    assert_int_equal(d->fault.sdo_abort_code, 0x06020000u);
    assert_int_equal(d->fault.sdo_index, 0x1016);
    assert_int_equal(d->phase, CIA402_DRIVE_HALTED);

    /* a fired watchdog in RUN: EMCY 0x8130, then the drive's pre-operational heartbeat */
    setup(NULL);
    t = bring_up_checked();
    PUSH(fc, 0x080 + NODE, t + 5, 0x30, 0x81, 0x11, 0, 0, 0, 0, 0);
    assert_int_equal(run(d, fc, t += 10), COSLAM_E_DRIVE_FAULT);
    assert_int_equal(d->fault.reason, CIA402_FAULT_EMCY);
    assert_int_equal(d->fault.emcy_code, 0x8130);
    const size_t n = fc->n_sent;
    assert_int_equal(cia402_drive_fault_reset(d, t), COSLAM_OK);
    assert_int_equal(d->phase, CIA402_DRIVE_BOOT); /* not the controlword reset */
    assert_int_equal(d->fault.reason, CIA402_FAULT_NONE);
    assert_true(fc->n_sent > n);
    ASSERT_FRAME(fc->sent[n], 0x000, 0x81, NODE);

    /* the fault is classified by the EMCY that latched it: a device EMCY
     * after the 0x8130 (its 0x6007 fault reaction) still gets the bring-up */
    setup(NULL);
    t = bring_up_checked();
    PUSH(fc, 0x080 + NODE, t + 5, 0x30, 0x81, 0x11, 0, 0, 0, 0, 0);
    PUSH(fc, 0x080 + NODE, t + 6, 0x10, 0x23, 0x01, 0, 0, 0, 0, 0);
    assert_int_equal(run(d, fc, t += 10), COSLAM_E_DRIVE_FAULT);
    assert_int_equal(d->fault.emcy_code, 0x2310); /* the last one received */
    assert_int_equal(cia402_drive_fault_reset(d, t), COSLAM_OK);
    assert_int_equal(d->phase, CIA402_DRIVE_BOOT);
    /* another communication EMCY (0x8110, CAN overrun) leaves the drive
     * OPERATIONAL: the CiA 402 fault reset, in RUN */
    setup(NULL);
    t = bring_up_checked();
    PUSH(fc, 0x080 + NODE, t + 5, 0x10, 0x81, 0x11, 0, 0, 0, 0, 0);
    assert_int_equal(run(d, fc, t += 10), COSLAM_E_DRIVE_FAULT);
    assert_int_equal(cia402_drive_fault_reset(d, t), COSLAM_OK);
    assert_int_equal(d->phase, CIA402_DRIVE_RUN);
    assert_int_equal(d->reset_requested, 1);
}

static void test_user_sdo(void **state)
{
    (void)state;
    uint64_t t = bring_up_checked();
    fake_can_t *fc = &g_fc;
    cia402_drive_t *d = &g_d;
    uint32_t v = 0;
    uint32_t ab = 0;
    assert_int_equal(cia402_drive_sdo_state(d, &v, &ab), CIA402_SDO_IDLE); /* bring-up SDOs are not the user's */
    assert_int_equal(cia402_drive_sdo_read(d, 0x1018, 4, t), COSLAM_OK);
    ASSERT_FRAME(*last_sent(fc), 0x600 + NODE, 0x40, 0x18, 0x10, 0x04, 0, 0, 0, 0);
    assert_int_equal(cia402_drive_sdo_read(d, 0x1018, 3, t), COSLAM_E_DRIVE_STATE); /* busy */
    assert_int_equal(cia402_drive_sdo_state(d, &v, &ab), CIA402_SDO_BUSY);
    PUSH(fc, 0x580 + NODE, t + 10, 0x43, 0x18, 0x10, 0x04, 0xEF, 0xBE, 0xAD, 0xDE);
    PUSH(fc, 0x700 + NODE, t + 10, 0x05);
    run(d, fc, t += 100);
    assert_int_equal(cia402_drive_sdo_state(d, &v, &ab), CIA402_SDO_DONE);
    assert_int_equal(v, 0xDEADBEEFu);
    assert_int_equal(cia402_drive_sdo_write(d, 0x6041, 0, 1, 2, t), COSLAM_OK);
    ASSERT_FRAME(*last_sent(fc), 0x600 + NODE, 0x2B, 0x41, 0x60, 0x00, 0x01, 0x00, 0, 0);
    PUSH(fc, 0x580 + NODE, t + 10, 0x80, 0x41, 0x60, 0x00, 0x02, 0x00, 0x01, 0x06);
    run(d, fc, t += 100);
    assert_int_equal(cia402_drive_sdo_state(d, &v, &ab), CIA402_SDO_ABORTED);
    assert_int_equal(ab, CANOPEN_SDO_ABORT_READ_ONLY);
    /* a user SDO failure is not a drive fault */
    assert_int_equal(d->fault.reason, CIA402_FAULT_NONE);
    assert_int_equal(cia402_drive_sdo_write(d, 0x6041, 0, 1, 5, t), COSLAM_E_ARG);
    /* not before RUN */
    setup(NULL);
    assert_int_equal(cia402_drive_sdo_read(&g_d, 0x1018, 1, 0), COSLAM_E_DRIVE_STATE);
}

static void test_malformed_and_foreign_frames(void **state)
{
    (void)state;
    uint64_t t = enable_checked(bring_up_checked());
    fake_can_t *fc = &g_fc;
    cia402_drive_t *d = &g_d;
    const uint32_t bad0 = d->rx_malformed;
    PUSH(fc, 0x180 + NODE, t, 0x08, 0x02, 0, 0);                 /* TPDO dlc 4 */
    PUSH(fc, 0x700 + NODE, t, 0x05, 0x00);                       /* heartbeat dlc 2 */
    PUSH(fc, 0x080 + NODE, t, 0x10, 0x23);                       /* EMCY dlc 2 */
    PUSH(fc, 0x580 + NODE, t, 0x60, 0x17);                       /* SDO dlc 2, none pending */
    PUSH(fc, 0x180 + NODE + 1, t, 0x08, 0x02, 0, 0, 0, 0);       /* another node's FAULT */
    PUSH(fc, 0x080 + NODE + 1, t, 0x10, 0x23, 0x01, 0, 0, 0, 0, 0);
    PUSH(fc, 0x080 + NODE, t, 0x00, 0x00, 0x00, 0, 0, 0, 0, 0);  /* "no error" EMCY: not a fault */
    PUSH(fc, 0x700 + NODE, t, 0x05);
    assert_int_equal(run(d, fc, t += 100), COSLAM_OK);
    assert_int_equal(d->rx_malformed, bad0 + 3);
    assert_int_equal(d->emcy_count, 1);
    assert_int_equal(d->fault.reason, CIA402_FAULT_NONE);
    assert_true(cia402_drive_is_enabled(d));
    hal_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = 0x185;
    f.flags = HAL_CAN_FLAG_EXT;
    f.dlc = 6;
    assert_int_equal(cia402_drive_on_frame(d, &f), CIA402_RX_NOT_MINE);
}

static void test_send_failures(void **state)
{
    (void)state;
    fake_can_t *fc = &g_fc;
    cia402_drive_t *d = &g_d;
    /* a full transmit queue: the NMT reset is retried at the next poll */
    fc->send_status = HAL_E_TIMEOUT;
    fc->send_fail_count = 1;
    cia402_drive_start(d, 0);
    assert_int_equal(fc->n_sent, 0);
    assert_int_equal(d->tx_failures, 1);
    assert_int_equal(run(d, fc, 10), COSLAM_OK);
    assert_int_equal(fc->n_sent, 1);
    ASSERT_FRAME(fc->sent[0], 0x000, 0x81, NODE);
    /* a bus error is a BUS fault */
    fc->send_status = HAL_E_IO;
    fc->send_fail_count = 1;
    cia402_drive_start(d, 20);
    assert_int_equal(d->fault.reason, CIA402_FAULT_BUS);
    assert_int_equal(d->fault.hal_status, HAL_E_IO);
    /* config checks */
    cia402_drive_config_t c = cia402_drive_config_default(0);
    assert_int_equal(cia402_drive_init(d, &c, &fc->can), COSLAM_E_ARG);
    c = cia402_drive_config_default(1);
    c.heartbeat_timeout_us = 100000; /* not above the 100 ms period */
    assert_int_equal(cia402_drive_init(d, &c, &fc->can), COSLAM_E_ARG);
    c = cia402_drive_config_default(1);
    assert_int_equal(cia402_drive_init(d, &c, NULL), COSLAM_E_ARG);
    assert_int_equal(cia402_drive_init(d, &c, &fc->can), COSLAM_OK);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_canopen_frames),
        cmocka_unit_test(test_canopen_parse),
        cmocka_unit_test(test_canopen_classify),
        cmocka_unit_test(test_statusword_decoding),
        cmocka_unit_test(test_controlword_table),
        cmocka_unit_test_setup(test_bring_up_and_enable, setup),
        cmocka_unit_test_setup(test_disable_and_quick_stop_transitions, setup),
        cmocka_unit_test_setup(test_emcy_fault_and_fault_reset, setup),
        cmocka_unit_test_setup(test_device_fault_without_emcy, setup),
        cmocka_unit_test_setup(test_sdo_abort_during_config, setup),
        cmocka_unit_test_setup(test_sdo_timeout_and_boot_timeout, setup),
        cmocka_unit_test_setup(test_config_rejects_bad_replies, setup),
        cmocka_unit_test_setup(test_heartbeat_loss, setup),
        cmocka_unit_test_setup(test_watchdog_config, setup),
        cmocka_unit_test_setup(test_nmt_and_pdo_supervision, setup),
        cmocka_unit_test_setup(test_user_sdo, setup),
        cmocka_unit_test_setup(test_malformed_and_foreign_frames, setup),
        cmocka_unit_test_setup(test_send_failures, setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
