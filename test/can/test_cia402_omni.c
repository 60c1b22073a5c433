/* The three-wheel base against a fake hal_can with a tiny scripted
 * responder: filters, bring-up of three nodes, RPDO velocities from a body
 * velocity, fault on one wheel stopping all, bus errors, and odometry
 * integrated from stamped TPDOs against the closed-form arc. */
#include "../slam/test_util.h"

#include <string.h>

#include "cia402/canopen.h"
#include "cia402/cia402_omni.h"
#include "coslam/pose2.h"
#include "coslam/rng.h"
#include "fake_can.h"

static fake_can_t g_fc;
static cia402_omni_t g_o;

/* The scripted drives: answer NMT and SDO, reflect the controlword into a
 * statusword TPDO with velocity actual = target (ideal drives). */
typedef struct {
    size_t seen;          /* sent frames already answered */
    int faulted[128];     /* node in FAULT until a 0x80 controlword */
    int tpdo_on;          /* answer RPDOs with TPDOs */
    int hb_on;            /* nodes 1..3 send an OPERATIONAL heartbeat every 100 ms */
    uint64_t next_hb;
} responder_t;

static responder_t g_r;

static void respond(fake_can_t *fc, responder_t *r, uint64_t now)
{
    if (r->hb_on && now >= r->next_hb) {
        const uint8_t op = 0x05;
        for (uint32_t node = 1; node <= 3; ++node) fake_can_push(fc, 0x700u + node, &op, 1, now);
        r->next_hb = now + 100000u;
    }
    for (; r->seen < fc->n_sent; ++r->seen) {
        const hal_can_frame_t *f = &fc->sent[r->seen];
        uint8_t node = 0;
        const canopen_fn_t fn = canopen_classify(f, &node);
        if (fn == CANOPEN_FN_NMT) {
            const uint8_t st = f->data[0] == CANOPEN_NMT_RESET_NODE ? 0x00 : 0x05;
            fake_can_push(fc, 0x700u + f->data[1], &st, 1, now);
        } else if (fn == CANOPEN_FN_SDO_RX) {
            const uint16_t idx = canopen_get_u16(&f->data[1]);
            uint8_t rep[8] = {0x60, f->data[1], f->data[2], f->data[3], 0, 0, 0, 0};
            if (f->data[0] == 0x40) {
                uint32_t v = 0;
                if (idx == 0x6061) v = 3;
                if (idx == 0x6041) v = 0x0240;
                if (idx == 0x1018) v = 0x100u + node;
                rep[0] = 0x43;
                canopen_put_u32(&rep[4], v);
            }
            fake_can_push(fc, 0x580u + node, rep, 8, now);
        } else if (fn == CANOPEN_FN_RPDO1 && r->tpdo_on) {
            const uint16_t cw = canopen_get_u16(&f->data[0]);
            uint16_t sw = 0x0240;
            if (r->faulted[node]) {
                sw = 0x0208;
                if (cw == 0x80) {
                    r->faulted[node] = 0;
                    sw = 0x0240;
                }
            } else if (cw == 0x06) {
                sw = 0x0221;
            } else if (cw == 0x07) {
                sw = 0x0233;
            } else if (cw == 0x0F) {
                sw = 0x0237;
            }
            uint8_t tp[6];
            canopen_put_u16(&tp[0], sw);
            memcpy(&tp[2], &f->data[2], 4);
            fake_can_push(fc, 0x180u + node, tp, 6, now);
        }
    }
}

static uint64_t step_until(uint64_t t, int (*cond)(void), int max_ms)
{
    for (int i = 0; i < max_ms; ++i) {
        cia402_omni_poll(&g_o, t);
        respond(&g_fc, &g_r, t);
        t += 1000;
        if (cond != NULL && cond()) return t;
    }
    if (cond != NULL) fail_msg("condition not reached in %d ms", max_ms);
    return t;
}

static int is_running(void) { return cia402_omni_is_running(&g_o); }
static int is_enabled(void) { return cia402_omni_is_enabled(&g_o); }

static int setup(void **state)
{
    (void)state;
    fake_can_init(&g_fc);
    memset(&g_r, 0, sizeof g_r);
    g_r.tpdo_on = 1;
    const cia402_omni_config_t cfg = cia402_omni_config_default();
    assert_int_equal(cia402_omni_init(&g_o, &cfg, &g_fc.can), COSLAM_OK);
    return 0;
}

static const hal_can_frame_t *last_rpdo(uint8_t node)
{
    for (size_t i = g_fc.n_sent; i-- > 0;) {
        if (g_fc.sent[i].id == 0x200u + node) return &g_fc.sent[i];
    }
    fail_msg("no RPDO to node %u", node);
    return NULL;
}

static int32_t rpdo_velocity(const hal_can_frame_t *f) { return (int32_t)canopen_get_u32(&f->data[2]); }

static void test_config_and_start(void **state)
{
    (void)state;
    cia402_omni_config_t c = cia402_omni_config_default();
    c.node_id[2] = c.node_id[0];
    assert_int_equal(cia402_omni_init(&g_o, &c, &g_fc.can), COSLAM_E_ARG);
    c = cia402_omni_config_default();
    c.node_id[1] = 128;
    assert_int_equal(cia402_omni_init(&g_o, &c, &g_fc.can), COSLAM_E_ARG);
    c = cia402_omni_config_default();
    c.velocity_unit_rpm = 0.0;
    assert_int_equal(cia402_omni_init(&g_o, &c, &g_fc.can), COSLAM_E_ARG);
    c = cia402_omni_config_default();
    c.kinematics.wheel_radius_m = NAN;
    assert_int_equal(cia402_omni_init(&g_o, &c, &g_fc.can), COSLAM_E_ARG);
    c = cia402_omni_config_default();
    c.node_id[0] = 10;
    c.node_id[1] = 11;
    c.node_id[2] = 12;
    assert_int_equal(cia402_omni_init(&g_o, &c, &g_fc.can), COSLAM_OK);
    assert_int_equal(cia402_omni_start(&g_o, 0), COSLAM_OK);
    /* filters: EMCY, TPDO1, SDO tx, heartbeat of each node, exact match */
    assert_true(g_fc.filters_set);
    assert_int_equal(g_fc.n_filters, 12);
    const uint32_t want[12] = {0x08A, 0x18A, 0x58A, 0x70A, 0x08B, 0x18B, 0x58B, 0x70B, 0x08C, 0x18C, 0x58C, 0x70C};
    for (int i = 0; i < 12; ++i) {
        assert_int_equal(g_fc.filters[i].id, want[i]);
        assert_int_equal(g_fc.filters[i].mask, 0x7FF);
        assert_int_equal(g_fc.filters[i].flags, 0);
    }
    /* one NMT reset per node */
    assert_int_equal(g_fc.n_sent, 3);
    for (int k = 0; k < 3; ++k) {
        assert_int_equal(g_fc.sent[k].id, 0);
        assert_int_equal(g_fc.sent[k].data[0], 0x81);
        assert_int_equal(g_fc.sent[k].data[1], 10 + k);
    }
    step_until(1000, is_running, 100);
    for (int k = 0; k < 3; ++k) {
        assert_int_equal(g_o.drive[k].vendor_id, 0x100u + 10u + (unsigned)k);
    }
}

static uint64_t bring_up_and_enable(void)
{
    assert_int_equal(cia402_omni_start(&g_o, 0), COSLAM_OK);
    uint64_t t = step_until(1000, is_running, 100);
    assert_int_equal(cia402_omni_enable(&g_o, 1), COSLAM_OK);
    return step_until(t, is_enabled, 100);
}

static size_t count_master_heartbeats(size_t from)
{
    size_t n = 0;
    for (size_t i = from; i < g_fc.n_sent; ++i) {
        const hal_can_frame_t *f = &g_fc.sent[i];
        if (f->id != 0x77Fu) continue;
        assert_int_equal(f->dlc, 1);
        assert_int_equal(f->data[0], 0x05); /* OPERATIONAL */
        ++n;
    }
    return n;
}

/* The master heartbeat the drives' watchdog consumes: checked config, none
 * before start, every 50 ms from start on, through a fault, none when off. */
static void test_master_heartbeat(void **state)
{
    (void)state;
    cia402_omni_t o;
    cia402_omni_config_t c = cia402_omni_config_default();
    c.drive.master_node_id = 2; /* a wheel's id */
    assert_int_equal(cia402_omni_init(&o, &c, &g_fc.can), COSLAM_E_ARG);
    c = cia402_omni_config_default();
    c.master_heartbeat_period_ms = 101; /* one lost heartbeat would trip the 200 ms watchdog */
    assert_int_equal(cia402_omni_init(&o, &c, &g_fc.can), COSLAM_E_ARG);
    c.master_heartbeat_period_ms = 0;
    assert_int_equal(cia402_omni_init(&o, &c, &g_fc.can), COSLAM_E_ARG);
    c.master_heartbeat_period_ms = 100;
    assert_int_equal(cia402_omni_init(&o, &c, &g_fc.can), COSLAM_OK);

    /* not started: not the master yet */
    for (uint64_t t = 0; t < 200000; t += 1000) cia402_omni_poll(&g_o, t);
    assert_int_equal(count_master_heartbeats(0), 0);
    /* from start on: at 0, 50, ..., 1000 ms with 1 ms polls */
    uint64_t t = bring_up_and_enable();
    g_r.hb_on = 1; /* the test runs past the drives' heartbeat timeout */
    assert_true(count_master_heartbeats(0) >= 1u); /* the first poll sent one */
    assert_int_equal(g_o.master_hb_sent, count_master_heartbeats(0));
    g_fc.n_sent = 0; /* the recorder holds 512 frames: empty it between the windows */
    g_r.seen = 0;
    t = step_until(t, NULL, 1000);
    assert_int_equal(count_master_heartbeats(0), 20);
    /* a fault stops the wheels, not the master */
    const uint8_t em[8] = {0x10, 0x23, 0x01, 0, 0, 0, 0, 0};
    fake_can_push(&g_fc, 0x082, em, 8, t);
    g_r.faulted[2] = 1;
    g_fc.n_sent = 0;
    g_r.seen = 0;
    t = step_until(t, NULL, 500);
    assert_int_equal(g_o.fault.wheel, 1);
    assert_int_equal(count_master_heartbeats(0), 10);
    /* a refused send is counted and retried at the next poll, not dropped for a period */
    g_fc.send_status = HAL_E_BUSY;
    g_fc.send_fail_count = 1000000;
    const uint32_t fails = g_o.master_hb_failures;
    t = step_until(t, NULL, 60);
    assert_true(g_o.master_hb_failures > fails);
    g_fc.send_fail_count = 0;
    g_fc.n_sent = 0;
    g_r.seen = 0;
    t = step_until(t, NULL, 1);
    assert_int_equal(count_master_heartbeats(0), 1);

    /* released (a clean stop): NMT reset communication to each wheel, then no heartbeat */
    g_fc.n_sent = 0;
    g_r.seen = 0;
    assert_int_equal(cia402_omni_release(&g_o), COSLAM_OK);
    assert_int_equal(g_fc.n_sent, 3);
    for (int k = 0; k < 3; ++k) {
        assert_int_equal(g_fc.sent[k].id, 0);
        assert_int_equal(g_fc.sent[k].dlc, 2);
        assert_int_equal(g_fc.sent[k].data[0], 0x82);
        assert_int_equal(g_fc.sent[k].data[1], k + 1);
    }
    g_fc.n_sent = 0;
    for (int i = 0; i < 200; ++i) (void)cia402_omni_poll(&g_o, t += 1000);
    assert_int_equal(count_master_heartbeats(0), 0);
    assert_int_equal(cia402_omni_release(NULL), COSLAM_E_ARG);

    /* off: no heartbeat at all */
    setup(NULL);
    c = cia402_omni_config_default();
    c.drive.master_node_id = 0;
    assert_int_equal(cia402_omni_init(&g_o, &c, &g_fc.can), COSLAM_OK);
    t = bring_up_and_enable();
    g_r.hb_on = 1;
    step_until(t, NULL, 500);
    assert_int_equal(count_master_heartbeats(0), 0);
    assert_true(cia402_omni_is_enabled(&g_o));
}

/* The drives' power-on boot-up messages, queued before the master started
 * (the robot process starts after the drives): read and dropped at start,
 * not taken for the answers to the NMT resets (then the real boot-ups
 * looked like reboots in CONFIG: an NMT fault at every start). */
static void test_frames_queued_before_start_are_stale(void **state)
{
    (void)state;
    const uint8_t boot = 0x00;
    for (uint32_t node = 1; node <= 3; ++node) fake_can_push(&g_fc, 0x700u + node, &boot, 1, 0);
    const uint8_t em[8] = {0x10, 0x23, 0x01, 0, 0, 0, 0, 0}; /* and an EMCY of a previous run */
    fake_can_push(&g_fc, 0x082, em, 8, 0);
    (void)bring_up_and_enable();
    cia402_omni_fault_t rep;
    assert_int_equal(cia402_omni_get_fault(&g_o, &rep), COSLAM_E_EMPTY);
    assert_int_equal(g_o.rx_stale, 4);
    assert_true(cia402_omni_is_enabled(&g_o));
}

static void test_body_velocity_to_rpdo(void **state)
{
    (void)state;
    uint64_t t = bring_up_and_enable();
    assert_int_equal(cia402_omni_set_body_velocity(&g_o, 0.2, 0.0, 0.0), COSLAM_OK);
    t = step_until(t, NULL, 2);
    /* rim speeds -sin(a) * 0.2 for a = 60, 180, 300 deg; 0.1 rpm units */
    const double to_units = 16.0 / 0.040 * 60.0 / (2.0 * COSLAM_PI) / 0.1;
    const double rim[3] = {-0.2 * sqrt(3.0) / 2.0, 0.0, 0.2 * sqrt(3.0) / 2.0};
    for (uint8_t k = 0; k < 3; ++k) {
        const hal_can_frame_t *f = last_rpdo((uint8_t)(k + 1));
        assert_int_equal(f->dlc, 6);
        assert_int_equal(canopen_get_u16(&f->data[0]), 0x0F);
        assert_int_equal(rpdo_velocity(f), (int32_t)lround(rim[k] * to_units));
    }
    assert_int_equal(rpdo_velocity(last_rpdo(1)), -6616);
    /* measured velocity comes back through the TPDOs */
    double vx, vy, w;
    assert_int_equal(cia402_omni_measured_velocity(&g_o, &vx, &vy, &w), COSLAM_OK);
    ASSERT_NEAR(vx, 0.2, 1e-4);
    ASSERT_NEAR(vy, 0.0, 1e-4);
    ASSERT_NEAR(w, 0.0, 1e-3);
    /* saturation: a 10 m/s request is scaled to 3000 rpm on the fastest wheel */
    assert_int_equal(cia402_omni_set_body_velocity(&g_o, 10.0, 0.0, 0.0), COSLAM_OK);
    assert_int_equal(g_o.saturations, 1);
    step_until(t, NULL, 2);
    assert_int_equal(rpdo_velocity(last_rpdo(3)), 30000);
    assert_int_equal(rpdo_velocity(last_rpdo(1)), -30000);
    assert_int_equal(rpdo_velocity(last_rpdo(2)), 0);
    /* a NaN command is refused and stops the base */
    assert_int_equal(cia402_omni_set_body_velocity(&g_o, NAN, 0.0, 0.0), COSLAM_E_NUMERIC);
    step_until(t, NULL, 2);
    for (uint8_t k = 1; k <= 3; ++k) assert_int_equal(rpdo_velocity(last_rpdo(k)), 0);
    /* disable */
    assert_int_equal(cia402_omni_enable(&g_o, 0), COSLAM_OK);
    step_until(t, NULL, 2);
    for (uint8_t k = 1; k <= 3; ++k) assert_int_equal(canopen_get_u16(&last_rpdo(k)->data[0]), 0x00);
}

static void test_fault_on_one_wheel_stops_all(void **state)
{
    (void)state;
    uint64_t t = bring_up_and_enable();
    assert_int_equal(cia402_omni_set_body_velocity(&g_o, 0.1, 0.2, 0.3), COSLAM_OK);
    t = step_until(t, NULL, 5);
    for (uint8_t k = 1; k <= 3; ++k) assert_true(rpdo_velocity(last_rpdo(k)) != 0);
    cia402_omni_fault_t rep;
    assert_int_equal(cia402_omni_get_fault(&g_o, &rep), COSLAM_E_EMPTY);
    assert_int_equal(rep.wheel, -1);
    /* wheel 1 (node 2) reports over-current */
    const uint8_t em[8] = {0x10, 0x23, 0x01, 0, 0, 0, 0, 0};
    fake_can_push(&g_fc, 0x082, em, 8, t);
    g_r.faulted[2] = 1;
    const size_t n = g_fc.n_sent;
    assert_int_equal(cia402_omni_poll(&g_o, t), COSLAM_E_DRIVE_FAULT);
    /* in this same poll: every wheel gets quick stop and velocity 0 */
    int stopped[4] = {0, 0, 0, 0};
    for (size_t i = n; i < g_fc.n_sent; ++i) {
        const hal_can_frame_t *f = &g_fc.sent[i];
        if (f->id >= 0x201 && f->id <= 0x203 && canopen_get_u16(&f->data[0]) == 0x02 && rpdo_velocity(f) == 0) {
            stopped[f->id - 0x200] = 1;
        }
    }
    assert_true(stopped[1] && stopped[2] && stopped[3]);
    assert_int_equal(cia402_omni_get_fault(&g_o, &rep), COSLAM_OK);
    assert_int_equal(rep.wheel, 1);
    assert_int_equal(rep.node_id, 2);
    assert_int_equal(rep.info.reason, CIA402_FAULT_EMCY);
    assert_int_equal(rep.info.emcy_code, 0x2310);
    assert_int_equal(rep.faulted_mask, 0x2);
    /* commands are refused while the fault stands */
    assert_int_equal(cia402_omni_set_body_velocity(&g_o, 0.1, 0.0, 0.0), COSLAM_E_DRIVE_FAULT);
    assert_int_equal(cia402_omni_enable(&g_o, 1), COSLAM_E_DRIVE_FAULT);
    respond(&g_fc, &g_r, t);
    t = step_until(t + 1000, NULL, 20);
    for (uint8_t k = 1; k <= 3; ++k) assert_int_equal(rpdo_velocity(last_rpdo(k)), 0);
    assert_int_equal(canopen_get_u16(&last_rpdo(2)->data[0]), 0x00); /* node 2 is in FAULT: bit 7 low */
    assert_false(cia402_omni_is_enabled(&g_o));
    /* reset: node 2 gets the 0x80 edge, the report clears, all stay disabled */
    assert_int_equal(cia402_omni_fault_reset(&g_o, t), COSLAM_OK);
    t = step_until(t, NULL, 20);
    assert_int_equal(cia402_omni_get_fault(&g_o, &rep), COSLAM_E_EMPTY);
    assert_int_equal(cia402_omni_poll(&g_o, t), COSLAM_OK);
    for (uint8_t k = 1; k <= 3; ++k) assert_int_equal(canopen_get_u16(&last_rpdo(k)->data[0]), 0x00);
    assert_int_equal(cia402_omni_enable(&g_o, 1), COSLAM_OK);
    step_until(t, is_enabled, 50);
}

/* A drive that leaves OPERATION_ENABLED on its own (its quick-stop or STO
 * input: quick stop active, no fault) stops the base as a fault does, and
 * is not walked back to enabled by the master; a fault reset restarts it. */
static void test_drive_leaving_enabled_stops_the_base(void **state)
{
    (void)state;
    uint64_t t = bring_up_and_enable();
    assert_int_equal(cia402_omni_set_body_velocity(&g_o, 0.2, 0.0, 0.0), COSLAM_OK);
    t = step_until(t, NULL, 5);
    g_r.tpdo_on = 0;
    uint8_t tp[6];
    canopen_put_u16(&tp[0], 0x0207); /* node 3: quick stop active */
    canopen_put_u32(&tp[2], 0u);
    fake_can_push(&g_fc, 0x183, tp, 6, t);
    const size_t n = g_fc.n_sent;
    assert_int_equal(cia402_omni_poll(&g_o, t), COSLAM_E_DRIVE_FAULT);
    cia402_omni_fault_t rep;
    assert_int_equal(cia402_omni_get_fault(&g_o, &rep), COSLAM_OK);
    assert_int_equal(rep.wheel, 2);
    assert_int_equal(rep.info.reason, CIA402_FAULT_LEFT_ENABLED);
    /* in this same poll the other two get quick stop and velocity 0 */
    int stopped[4] = {0, 0, 0, 0};
    for (size_t i = n; i < g_fc.n_sent; ++i) {
        const hal_can_frame_t *f = &g_fc.sent[i];
        if (f->id >= 0x201 && f->id <= 0x203 && canopen_get_u16(&f->data[0]) == 0x02 && rpdo_velocity(f) == 0) {
            stopped[f->id - 0x200] = 1;
        }
    }
    assert_true(stopped[1] && stopped[2]);
    /* node 3 is never told to go back up while the fault stands */
    for (int i = 0; i < 20; ++i) {
        t += 1000;
        fake_can_push(&g_fc, 0x183, tp, 6, t);
        (void)cia402_omni_poll(&g_o, t);
        const uint16_t cw = canopen_get_u16(&last_rpdo(3)->data[0]);
        assert_true(cw != 0x06 && cw != 0x07 && cw != 0x0F);
        assert_int_equal(rpdo_velocity(last_rpdo(1)), 0);
    }
    assert_false(cia402_omni_is_enabled(&g_o));
    /* the wheel reaching enabled during the bring-up is not a fault */
    assert_int_equal(g_o.drive[0].fault.reason, CIA402_FAULT_NONE);
}

static void test_bus_errors(void **state)
{
    (void)state;
    uint64_t t = bring_up_and_enable();
    g_fc.receive_status = HAL_E_OVERFLOW;
    assert_int_equal(cia402_omni_poll(&g_o, t), COSLAM_OK);
    assert_int_equal(g_o.rx_overflows, 1);
    g_fc.receive_status = HAL_E_CORRUPT;
    assert_int_equal(cia402_omni_poll(&g_o, t), COSLAM_OK);
    assert_int_equal(g_o.rx_errors, 1);
    g_fc.receive_status = HAL_E_BUSY; /* "retry": not an error */
    assert_int_equal(cia402_omni_poll(&g_o, t), COSLAM_OK);
    assert_int_equal(g_o.rx_errors, 1);
    g_fc.receive_status = HAL_E_CLOSED;
    assert_int_equal(cia402_omni_poll(&g_o, t), COSLAM_E_DRIVE_FAULT);
    cia402_omni_fault_t rep;
    assert_int_equal(cia402_omni_get_fault(&g_o, &rep), COSLAM_OK);
    assert_int_equal(rep.info.reason, CIA402_FAULT_BUS);
    assert_int_equal(rep.info.hal_status, HAL_E_CLOSED);
    assert_int_equal(rep.faulted_mask, 0x7);
}

static void push_tpdo(uint8_t node, int32_t vel, uint64_t stamp)
{
    uint8_t tp[6];
    canopen_put_u16(&tp[0], 0x0237);
    canopen_put_u32(&tp[2], (uint32_t)vel);
    fake_can_push(&g_fc, 0x180u + node, tp, 6, stamp);
}

static void test_odometry_from_tpdos(void **state)
{
    (void)state;
    g_r.tpdo_on = 0; /* this test writes the TPDOs itself */
    assert_int_equal(cia402_omni_start(&g_o, 0), COSLAM_OK);
    uint64_t t = step_until(1000, is_running, 100);
    odo_increment_t u;
    uint64_t until = 1;
    assert_int_equal(cia402_omni_take_odometry(&g_o, &u, &until), COSLAM_E_EMPTY);
    assert_int_equal(until, 0);
    /* constant body velocity: TPDOs every 10 ms for 2 s */
    const double vx = 0.3, vy = 0.1, w = 0.5;
    double rpm[3];
    omni_kinematics_inverse(&g_o.cfg.kinematics, vx, vy, w, rpm);
    int32_t units[3];
    for (int k = 0; k < 3; ++k) units[k] = (int32_t)lround(rpm[k] / 0.1);
    const uint64_t t0 = t;
    for (int i = 0; i <= 200; ++i) {
        for (uint8_t k = 0; k < 3; ++k) push_tpdo((uint8_t)(k + 1), units[k], t0 + (uint64_t)i * 10000u);
        const uint8_t hb = 0x05;
        for (uint8_t k = 1; k <= 3; ++k) fake_can_push(&g_fc, 0x700u + k, &hb, 1, t0 + (uint64_t)i * 10000u);
        assert_int_equal(cia402_omni_poll(&g_o, t0 + (uint64_t)i * 10000u), COSLAM_OK);
    }
    assert_int_equal(cia402_omni_take_odometry(&g_o, &u, &until), COSLAM_OK);
    assert_int_equal(until, t0 + 2000000u);
    /* closed-form arc over 2 s; tolerance from the 0.1 rpm quantisation */
    const double T = 2.0;
    const double th = w * T;
    const double x = (sin(th) * vx + (cos(th) - 1.0) * vy) / w;
    const double y = ((1.0 - cos(th)) * vx + sin(th) * vy) / w;
    ASSERT_NEAR(u.dx, x, 2e-4);
    ASSERT_NEAR(u.dy, y, 2e-4);
    ASSERT_NEAR(u.dtheta, th, 2e-4);
    /* taken: the next take starts from zero */
    assert_int_equal(cia402_omni_take_odometry(&g_o, &u, &until), COSLAM_OK);
    ASSERT_NEAR(u.dx, 0.0, 0.0);
    ASSERT_NEAR(u.dtheta, 0.0, 0.0);
    /* all wheels report 0 at a known stamp: the trapezoid over the 5 ms
     * since the last sample is half the old speed */
    const uint64_t t1 = t0 + 2000000u;
    push_tpdo(1, 0, t1 + 5000);
    push_tpdo(2, 0, t1 + 5000);
    push_tpdo(3, 0, t1 + 5000);
    cia402_omni_poll(&g_o, t1 + 5000);
    cia402_omni_take_odometry(&g_o, &u, &until);
    const odo_increment_t five = motion_from_body_velocity(vx / 2, vy / 2, w / 2, 0.005);
    ASSERT_NEAR(u.dx, five.dx, 1e-6);
    ASSERT_NEAR(u.dtheta, five.dtheta, 1e-6);
    assert_int_equal(until, t1 + 5000);
    (void)t;
}

/* One cycle's TPDOs of the wheels in `mask` (bit k: wheel k) at body
 * velocity (vx, vy, w), with heartbeats, then a poll. */
static void cycle(uint8_t mask, double vx, double vy, double w, uint64_t stamp)
{
    double rpm[3];
    omni_kinematics_inverse(&g_o.cfg.kinematics, vx, vy, w, rpm);
    for (uint8_t k = 0; k < 3; ++k) {
        if (mask & (1u << k)) push_tpdo((uint8_t)(k + 1), (int32_t)lround(rpm[k] / 0.1), stamp);
        const uint8_t hb = 0x05;
        fake_can_push(&g_fc, 0x700u + k + 1u, &hb, 1, stamp);
    }
    (void)cia402_omni_poll(&g_o, stamp);
}

/* A wheel that falls silent, and a bus that does: its last speed never
 * stands for the motion, nothing is integrated across the gap, and the
 * odometry starts again once all three wheels report. */
static void test_odometry_gaps(void **state)
{
    (void)state;
    g_r.tpdo_on = 0;
    assert_int_equal(cia402_omni_start(&g_o, 0), COSLAM_OK);
    const uint64_t t0 = step_until(1000, is_running, 100);
    const double vx = 0.2, w = 0.4;
    odo_increment_t u;
    uint64_t t = t0;
    for (int i = 0; i <= 50; ++i, t += 10000u) cycle(7, vx, 0.0, w, t);
    assert_int_equal(cia402_omni_take_odometry(&g_o, &u, NULL), COSLAM_OK);
    ASSERT_NEAR(u.dtheta, w * 0.5, 2e-4);
    /* wheel 3 silent while it was turning; wheels 1 and 2 report 0 for 2 s */
    for (int i = 0; i < 200; ++i, t += 10000u) cycle(3, 0.0, 0.0, 0.0, t);
    assert_int_equal(cia402_omni_take_odometry(&g_o, &u, NULL), COSLAM_OK);
    /* at most what one PDO timeout (100 ms) at the old speeds could bridge;
     * its last speed held for the 2 s gave 0.8 rad */
    assert_true(fabs(u.dtheta) < 0.1 * w * 1.5);
    assert_true(hypot(u.dx, u.dy) < 0.1 * vx * 1.5);
    assert_true(g_o.odo_gaps >= 1u);
    /* it reports again: the odometry goes on from there */
    for (int i = 0; i <= 50; ++i, t += 10000u) cycle(7, vx, 0.0, w, t);
    assert_int_equal(cia402_omni_take_odometry(&g_o, &u, NULL), COSLAM_OK);
    ASSERT_NEAR(u.dtheta, w * 0.5, 2e-4);
    /* the bus silent for 5 s, then every wheel reports standing still:
     * nothing is bridged (the old blend gave 1 m at this speed) */
    const uint32_t gaps = g_o.odo_gaps;
    t += 5000000u;
    for (int i = 0; i < 5; ++i, t += 10000u) cycle(7, 0.0, 0.0, 0.0, t);
    assert_int_equal(cia402_omni_take_odometry(&g_o, &u, NULL), COSLAM_OK);
    assert_true(hypot(u.dx, u.dy) < 1e-9 && fabs(u.dtheta) < 1e-9);
    assert_int_equal(g_o.odo_gaps, gaps + 1u);
}

/* Random frames on the drives' COB-IDs (and around them) at every stage:
 * nothing crashes (the _san build checks memory), everything the driver
 * sends is a well-formed frame of the kinds it may send. */
static void test_random_frames(void **state)
{
    (void)state;
    rng_t rng;
    rng_seed(&rng, 402);
    const int n = COSLAM_TEST_FULL ? 2000000 : 20000;
    const uint32_t bases[8] = {0x000, 0x080, 0x180, 0x200, 0x580, 0x600, 0x700, 0x280};
    uint64_t t = 0;
    assert_int_equal(cia402_omni_start(&g_o, t), COSLAM_OK);
    for (int i = 0; i < n; ++i) {
        uint8_t data[8];
        for (int b = 0; b < 8; ++b) data[b] = (uint8_t)rng_below(&rng, 256);
        /* bias towards the commands the driver reacts to */
        if (rng_below(&rng, 4) == 0) data[0] = (uint8_t)(rng_below(&rng, 2) ? 0x00 : 0x05);
        const uint32_t id = bases[rng_below(&rng, 8)] + rng_below(&rng, 5);
        fake_can_push(&g_fc, id, data, (uint8_t)rng_below(&rng, 9), t);
        if (rng_below(&rng, 8) == 0) {
            cia402_omni_poll(&g_o, t);
            respond(&g_fc, &g_r, t);
            if (g_fc.n_sent > FAKE_CAN_CAP - 64) { /* keep the recorder from filling */
                for (size_t k = 0; k < g_fc.n_sent; ++k) {
                    const hal_can_frame_t *f = &g_fc.sent[k];
                    assert_true(hal_can_frame_is_valid(f));
                    const uint32_t fn = f->id & 0x780u;
                    assert_true(f->id == 0 || fn == 0x200u || fn == 0x600u || f->id == 0x77Fu);
                    assert_true(f->dlc == (f->id == 0 ? 2 : fn == 0x200u ? 6 : f->id == 0x77Fu ? 1 : 8));
                }
                g_fc.n_sent = 0;
                g_r.seen = 0;
            }
        }
        if (rng_below(&rng, 64) == 0) (void)cia402_omni_set_body_velocity(&g_o, rng_normal(&rng, 0, 1), 0.1, 0.2);
        if (rng_below(&rng, 512) == 0) (void)cia402_omni_fault_reset(&g_o, t);
        if (rng_below(&rng, 256) == 0) (void)cia402_omni_enable(&g_o, 1);
        t += rng_below(&rng, 3000);
    }
    odo_increment_t u;
    (void)cia402_omni_take_odometry(&g_o, &u, NULL);
    assert_true(motion_is_finite(u));
    assert_true(g_o.rx_frames > 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_config_and_start, setup),
        cmocka_unit_test_setup(test_master_heartbeat, setup),
        cmocka_unit_test_setup(test_frames_queued_before_start_are_stale, setup),
        cmocka_unit_test_setup(test_body_velocity_to_rpdo, setup),
        cmocka_unit_test_setup(test_fault_on_one_wheel_stops_all, setup),
        cmocka_unit_test_setup(test_bus_errors, setup),
        cmocka_unit_test_setup(test_drive_leaving_enabled_stops_the_base, setup),
        cmocka_unit_test_setup(test_odometry_from_tpdos, setup),
        cmocka_unit_test_setup(test_odometry_gaps, setup),
        cmocka_unit_test_setup(test_random_frames, setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
