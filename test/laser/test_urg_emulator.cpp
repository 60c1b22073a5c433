// The URG emulator on its own (byte-exact replies against the published
// SCIP examples, SCIP 1.1 start-up, chopped reads) and end to end with the
// SCIP 2.0 driver: a ray-cast room gives the expected ranges within the
// noise, the 24-bit stamp wraps cleanly, injected faults are counted one for
// one and the following scans are good, and the scans feed the occupancy
// grid and the obstacle behaviour.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "coslam/obstacle.h"
#include "coslam/occ_grid.h"
#include "urg/urg_emulator.h"
#include "urg/urg_scip2.h"

using coslam::sim::UrgEmulator;
using coslam::sim::UrgEmulatorConfig;
using coslam::sim::UrgFault;

namespace {

constexpr uint64_t kTurnUs = 100000;
constexpr double kPi = 3.14159265358979323846;

// Inside walls of the box [x0, x1] x [y0, y1] seen from (x, y) along th.
double box_range(double x, double y, double th, double x0, double x1, double y0, double y1)
{
    const double c = std::cos(th), s = std::sin(th);
    double best = INFINITY;
    if (c > 1e-12) best = std::fmin(best, (x1 - x) / c);
    if (c < -1e-12) best = std::fmin(best, (x0 - x) / c);
    if (s > 1e-12) best = std::fmin(best, (y1 - y) / s);
    if (s < -1e-12) best = std::fmin(best, (y0 - y) / s);
    return best;
}

// A 4 m x 3 m room; the sensor at (1.3, 0.9) facing 20 degrees.
struct Room {
    double sx = 1.3, sy = 0.9, sth = 0.35;
    double truth(double a) const { return box_range(sx, sy, sth + a, 0.0, 4.0, 0.0, 3.0); }
};

std::string drain(hal_serial_t *s)
{
    std::string out;
    uint8_t buf[512];
    size_t n = 0;
    while (hal_serial_read(s, buf, sizeof buf, &n, 0) == HAL_OK) out.append(reinterpret_cast<char *>(buf), n);
    return out;
}

void send(hal_serial_t *s, const std::string &cmd)
{
    ASSERT_EQ(hal_serial_write(s, reinterpret_cast<const uint8_t *>(cmd.data()), cmd.size(), 0), HAL_OK);
}

double sigma_of(const UrgEmulatorConfig &c, double r)
{
    return std::max(c.noise_sigma_m, c.noise_rel * r);
}

class DriverWithEmulator : public ::testing::Test {
protected:
    void make(const UrgEmulatorConfig &cfg)
    {
        cfg_ = cfg;
        emu_ = std::make_unique<UrgEmulator>(cfg, [this](double a) { return room_.truth(a); });
        ASSERT_EQ(urg_scip2_init(&urg_, emu_->serial(), nullptr), COSLAM_OK);
        ASSERT_EQ(urg_scip2_enter_scip2(&urg_), COSLAM_OK);
        ASSERT_EQ(urg_scip2_read_params(&urg_, nullptr), COSLAM_OK);
    }
    void start_md(uint8_t n_scans = 0)
    {
        ASSERT_EQ(urg_scip2_start_md(&urg_, 44, 725, 1, 0, n_scans), COSLAM_OK);
    }
    // Every valid point of scan_ against the room, as z-scores.
    void check_ranges(std::vector<double> *z)
    {
        static double r[COSLAM_MAX_SCAN_POINTS], a[COSLAM_MAX_SCAN_POINTS];
        size_t n = 0;
        ASSERT_EQ(urg_scip2_scan_polar(urg_scip2_params(&urg_), &scan_, 0, r, a, COSLAM_MAX_SCAN_POINTS, &n), COSLAM_OK);
        ASSERT_EQ(n, 682u);
        for (size_t i = 0; i < n; ++i) {
            const double t = room_.truth(a[i]);
            ASSERT_TRUE(std::isfinite(r[i])) << "point " << i << " truth " << t;
            const double s = sigma_of(cfg_, t);
            // 6 sigma: P(|z| > 6) = 2e-9, safe over the 3.4e6 points of a full run
            ASSERT_LE(std::fabs(r[i] - t), 6.0 * s + 0.0005) << "point " << i;
            if (z) z->push_back((r[i] - t) / s);
        }
    }
    UrgEmulatorConfig cfg_;
    Room room_;
    std::unique_ptr<UrgEmulator> emu_;
    urg_scip2_t urg_{};
    urg_scip2_scan_t scan_{};
};

} // namespace

// ---------------------------------------------------------------------------
// The emulator alone
// ---------------------------------------------------------------------------

TEST(UrgEmulator, RepliesMatchPublishedExamplesByteForByte)
{
    UrgEmulatorConfig c;
    c.start_in_scip2 = true;
    UrgEmulator emu(c, [](double) { return 1.0; });
    send(emu.serial(), "PP\n");
    EXPECT_EQ(drain(emu.serial()),
              "PP\n00P\nMODL:URG-04LX(Hokuyo Automatic Co.,Ltd.);N\nDMIN:20;4\nDMAX:5600;_\nARES:1024;\\\n"
              "AMIN:44;7\nAMAX:725;o\nAFRT:384;6\nSCAN:600;e\n\n");
    send(emu.serial(), "VV\n");
    EXPECT_EQ(drain(emu.serial()), "VV\n00P\nVEND:Hokuyo Automatic Co.,Ltd.;[\nPROD:SOKUIKI Sensor URG-04LX;[\n"
                                   "FIRM:3.1.00(18/Jan./2007);`\nPROT:SCIP 2.0;N\nSERI:H0614967;V\n\n");
    send(emu.serial(), "BM\r\n"); // CR LF terminated works too
    EXPECT_EQ(drain(emu.serial()), "BM\n00P\n\n");
    send(emu.serial(), "BM\n");
    EXPECT_EQ(drain(emu.serial()), "BM\n02R\n\n");
    send(emu.serial(), "GD0044004601\n");
    const std::string gd = drain(emu.serial());
    ASSERT_EQ(gd.substr(0, 17), "GD0044004601\n00P\n");
    EXPECT_EQ(gd.size(), 17u + 6u + 11u + 1u); // stamp line, one data line of 9 + sum, empty line
    send(emu.serial(), "MD0044072501000\n");
    EXPECT_EQ(drain(emu.serial()), "MD0044072501000\n00P\n\n");
    send(emu.serial(), "MD0800072501000\n"); // end < start
    EXPECT_EQ(drain(emu.serial()), "MD0800072501000\n05U\n\n");
    send(emu.serial(), "MD0044080001000\n"); // beyond step 768
    EXPECT_EQ(drain(emu.serial()), "MD0044080001000\n04T\n\n");
    send(emu.serial(), "XX\n");
    EXPECT_EQ(drain(emu.serial()), "XX\n0Ee\n\n");
    send(emu.serial(), "QT\n");
    EXPECT_EQ(drain(emu.serial()), "QT\n00P\n\n");
    send(emu.serial(), "GD0044072501\n"); // laser off now
    EXPECT_EQ(drain(emu.serial()), "GD0044072501\n10Q\n\n");
}

TEST(UrgEmulator, StartsInScip11AndSwitches)
{
    UrgEmulator emu(UrgEmulatorConfig{}, [](double) { return 1.0; });
    send(emu.serial(), "VV\n");
    EXPECT_EQ(drain(emu.serial()), ""); // SCIP 1.1 is not emulated
    send(emu.serial(), "SCIP2.0\n");
    EXPECT_EQ(drain(emu.serial()), "SCIP2.0\n0\n\n");
    send(emu.serial(), "SCIP2.0\n");
    EXPECT_EQ(drain(emu.serial()), "SCIP2.0\n0Ee\n\n");
    EXPECT_EQ(emu.stats().unknown_commands, 2u);
}

TEST(UrgEmulator, ScanTimingAndStampEncoding)
{
    UrgEmulatorConfig c;
    c.start_in_scip2 = true;
    c.timer_offset_ms = 16000000 - 300; // turn 3 starts at 16,000,000 ms ("m2@0")
    UrgEmulator emu(c, [](double) { return 2.0; });
    send(emu.serial(), "MD0044004600000\n");
    drain(emu.serial());
    emu.set_time_us(399999);
    EXPECT_EQ(emu.stats().scans_sent, 3u); // turns 0, 1, 2 complete
    drain(emu.serial());
    emu.set_time_us(400000);
    const std::string m = drain(emu.serial());
    EXPECT_EQ(m.substr(0, 26), "MD0044004600000\n99b\nm2@0?\n");
}

TEST(UrgEmulator, ChoppedReadsDeliverTheSameBytes)
{
    UrgEmulatorConfig c;
    c.start_in_scip2 = true;
    UrgEmulatorConfig chopped = c;
    chopped.max_read_chunk = 5;
    UrgEmulator a(c, [](double x) { return 2.0 + x; });
    UrgEmulator b(chopped, [](double x) { return 2.0 + x; });
    for (UrgEmulator *e : {&a, &b}) {
        send(e->serial(), "MD0044072501000\n");
        e->set_time_us(5 * kTurnUs);
    }
    std::string whole = drain(a.serial()), pieces;
    uint8_t buf[100];
    size_t n = 0, reads = 0;
    while (hal_serial_read(b.serial(), buf, sizeof buf, &n, 0) == HAL_OK) {
        ASSERT_GE(n, 1u);
        ASSERT_LE(n, 5u);
        pieces.append(reinterpret_cast<char *>(buf), n);
        ++reads;
    }
    EXPECT_EQ(pieces, whole); // chopping never changes the ranges
    EXPECT_GT(reads, whole.size() / 5);
    EXPECT_EQ(a.stats().scans_sent, 5u);
}

// ---------------------------------------------------------------------------
// Driver + emulator
// ---------------------------------------------------------------------------

TEST_F(DriverWithEmulator, ConnectSequence)
{
    make(UrgEmulatorConfig{});
    EXPECT_TRUE(emu_->scip2());
    const urg_scip2_params_t *p = urg_scip2_params(&urg_);
    EXPECT_STREQ(p->model, "URG-04LX(Hokuyo Automatic Co.,Ltd.)");
    EXPECT_EQ(p->dmin_mm, 20u);
    EXPECT_EQ(p->dmax_mm, 5600u);
    EXPECT_EQ(p->ares, 1024u);
    EXPECT_EQ(p->amin, 44u);
    EXPECT_EQ(p->amax, 725u);
    EXPECT_EQ(p->afrt, 384u);
    urg_scip2_version_t v;
    ASSERT_EQ(urg_scip2_read_version(&urg_, &v), COSLAM_OK);
    EXPECT_STREQ(v.serial, "H0614967");
    urg_scip2_info_t info;
    ASSERT_EQ(urg_scip2_read_info(&urg_, &info), COSLAM_OK);
    EXPECT_EQ(info.laser_on, 0);
    ASSERT_EQ(urg_scip2_laser_on(&urg_), COSLAM_OK);
    ASSERT_EQ(urg_scip2_read_info(&urg_, &info), COSLAM_OK);
    EXPECT_EQ(info.laser_on, 1);
    EXPECT_TRUE(emu_->laser_on());
    ASSERT_EQ(urg_scip2_laser_off(&urg_), COSLAM_OK);
    EXPECT_FALSE(emu_->laser_on());
}

TEST_F(DriverWithEmulator, RoomRangesWithinNoise)
{
    make(UrgEmulatorConfig{});
    start_md();
    std::vector<double> z;
    uint64_t prev = 0;
    const int n_scans = COSLAM_TEST_FULL ? 200 : 20;
    for (int k = 0; k < n_scans; ++k) {
        // nothing before the turn completes
        emu_->advance_us(kTurnUs - 1);
        ASSERT_EQ(urg_scip2_read_scan(&urg_, &scan_, 0), COSLAM_E_URG_TIMEOUT);
        emu_->advance_us(1);
        ASSERT_EQ(urg_scip2_read_scan(&urg_, &scan_, 0), COSLAM_OK) << "scan " << k;
        check_ranges(&z);
        if (k > 0) {
            EXPECT_EQ(scan_.stamp_us - prev, kTurnUs);
        }
        prev = scan_.stamp_us;
    }
    double mean = 0, var = 0;
    for (double v : z) mean += v;
    mean /= static_cast<double>(z.size());
    for (double v : z) var += (v - mean) * (v - mean);
    const double sd = std::sqrt(var / static_cast<double>(z.size() - 1));
    EXPECT_NEAR(mean, 0.0, 0.05);
    EXPECT_NEAR(sd, 1.0, 0.05); // the configured noise, no more, no less
    const urg_scip2_stats_t *s = urg_scip2_stats(&urg_);
    EXPECT_EQ(s->scans_ok, static_cast<uint32_t>(n_scans));
    EXPECT_EQ(s->err_timeout + s->err_checksum + s->err_line + s->err_garbage + s->err_echo, 0u);
}

TEST_F(DriverWithEmulator, TimestampWrapsIntoMonotonicStamp)
{
    UrgEmulatorConfig c;
    c.timer_offset_ms = (1u << 24) - 250; // wraps 250 ms into the run
    make(c);
    start_md();
    uint64_t prev = 0;
    for (int k = 0; k < 6; ++k) {
        emu_->advance_us(kTurnUs);
        ASSERT_EQ(urg_scip2_read_scan(&urg_, &scan_, 0), COSLAM_OK);
        if (k > 0) {
            EXPECT_EQ(scan_.stamp_us, prev + kTurnUs) << "scan " << k;
        }
        prev = scan_.stamp_us;
    }
    EXPECT_EQ(scan_.raw_stamp_ms, 250u); // turn 5 starts at 500 ms: (2^24 - 250 + 500) mod 2^24
    EXPECT_EQ(urg_scip2_stats(&urg_)->stamp_wraps, 1u);
    EXPECT_EQ(urg_scip2_stats(&urg_)->stamp_backwards, 0u);
}

TEST_F(DriverWithEmulator, InjectedFaultsAreCountedAndTheNextScanIsGood)
{
    make(UrgEmulatorConfig{});
    start_md();
    struct {
        int at;
        UrgFault f;
        coslam_status_t expect;
    } plan[] = {{2, UrgFault::BadChecksum, COSLAM_E_URG_CHECKSUM},
                {5, UrgFault::TruncatedLine, COSLAM_E_URG_LINE},
                {8, UrgFault::Garbage, COSLAM_E_URG_GARBAGE}};
    int ok = 0;
    for (int k = 0; k < 12; ++k) {
        coslam_status_t expect = COSLAM_OK;
        for (auto &p : plan) {
            if (p.at == k) {
                emu_->inject(p.f);
                expect = p.expect;
            }
        }
        emu_->advance_us(kTurnUs);
        const coslam_status_t st = urg_scip2_read_scan(&urg_, &scan_, 0);
        ASSERT_EQ(st, expect) << "scan " << k << ": " << coslam_status_str(st);
        if (st == COSLAM_OK) {
            ++ok;
            check_ranges(nullptr);
        }
    }
    const urg_scip2_stats_t *s = urg_scip2_stats(&urg_);
    EXPECT_EQ(ok, 9);
    EXPECT_EQ(s->scans_ok, 9u);
    EXPECT_EQ(s->err_checksum, 1u);
    EXPECT_EQ(s->err_line, 1u);
    EXPECT_EQ(s->err_garbage, 1u);
    EXPECT_EQ(s->resyncs, 3u);
    EXPECT_EQ(s->err_timeout + s->err_echo, 0u);
}

TEST_F(DriverWithEmulator, RandomFaultsAndSplitReadsAccountedOneForOne)
{
    UrgEmulatorConfig c;
    c.seed = 2024;
    c.p_bad_checksum = 0.08;
    c.p_truncated_line = 0.08;
    c.p_garbage = 0.08;
    c.max_read_chunk = 13;
    make(c);
    start_md();
    const int n_scans = COSLAM_TEST_FULL ? 5000 : 400;
    for (int k = 0; k < n_scans; ++k) {
        emu_->advance_us(kTurnUs);
        for (;;) {
            const coslam_status_t st = urg_scip2_read_scan(&urg_, &scan_, 0);
            if (st == COSLAM_E_URG_TIMEOUT) break;
            if (st == COSLAM_OK) check_ranges(nullptr);
        }
    }
    const auto &f = emu_->stats().faults;
    const urg_scip2_stats_t *s = urg_scip2_stats(&urg_);
    EXPECT_GT(f[0] + f[1] + f[2], static_cast<uint64_t>(n_scans) / 10); // faults did happen
    EXPECT_EQ(s->err_checksum, f[0]);
    EXPECT_EQ(s->err_line, f[1]);
    EXPECT_EQ(s->err_garbage, f[2]);
    EXPECT_EQ(s->scans_ok, emu_->stats().scans_sent - f[0] - f[1] - f[2]);
    EXPECT_EQ(s->err_timeout + s->err_echo + s->err_io, 0u);
}

TEST_F(DriverWithEmulator, GdFiniteMdAndQtWhileStreaming)
{
    make(UrgEmulatorConfig{});
    // GD needs the laser
    ASSERT_EQ(urg_scip2_get_scan(&urg_, 44, 725, 1, &scan_), COSLAM_E_URG_STATUS);
    EXPECT_STREQ(urg_scip2_last_status(&urg_), "10");
    ASSERT_EQ(urg_scip2_laser_on(&urg_), COSLAM_OK);
    emu_->advance_us(3 * kTurnUs + 5000);
    ASSERT_EQ(urg_scip2_get_scan(&urg_, 44, 725, 1, &scan_), COSLAM_OK);
    check_ranges(nullptr);
    EXPECT_EQ(scan_.raw_stamp_ms, 200u); // the last complete turn started at 200 ms
    // MD of 3 scans, then it stops by itself (and the laser goes off); the
    // first scan is the turn starting at the next 100 ms boundary
    emu_->set_time_us(4 * kTurnUs);
    start_md(3);
    for (int k = 0; k < 3; ++k) {
        emu_->advance_us(kTurnUs);
        ASSERT_EQ(urg_scip2_read_scan(&urg_, &scan_, 0), COSLAM_OK);
        EXPECT_EQ(scan_.remaining, 2 - k);
    }
    EXPECT_FALSE(urg_scip2_is_streaming(&urg_));
    EXPECT_FALSE(emu_->streaming());
    EXPECT_FALSE(emu_->laser_on());
    EXPECT_EQ(urg_scip2_read_scan(&urg_, &scan_, 0), COSLAM_E_EMPTY);
    // unlimited MD; three scans pile up unread, then QT
    start_md(0);
    emu_->advance_us(3 * kTurnUs + 50000);
    ASSERT_EQ(urg_scip2_laser_off(&urg_), COSLAM_OK);
    EXPECT_EQ(urg_scip2_stats(&urg_)->messages_skipped, 3u);
    EXPECT_FALSE(emu_->streaming());
    EXPECT_EQ(emu_->queued_bytes(), 0u);
}

TEST_F(DriverWithEmulator, ScansFeedGridAndObstacleBehaviour)
{
    make(UrgEmulatorConfig{});
    // robot at (2.0, 1.5) facing +x; the east wall (x = 4) is 0.5 m ahead of
    // the sensor at x = 3.5
    room_.sx = 3.5;
    room_.sy = 1.5;
    room_.sth = 0.0;
    start_md();
    emu_->advance_us(kTurnUs);
    ASSERT_EQ(urg_scip2_read_scan(&urg_, &scan_, 0), COSLAM_OK);
    static double r[COSLAM_MAX_SCAN_POINTS], a[COSLAM_MAX_SCAN_POINTS];
    size_t n = 0;
    ASSERT_EQ(urg_scip2_scan_polar(urg_scip2_params(&urg_), &scan_, URG_SCIP2_POLAR_CODE0_NO_RETURN, r, a,
                                   COSLAM_MAX_SCAN_POINTS, &n),
              COSLAM_OK);

    static occ_grid_t grid;
    ASSERT_EQ(occ_grid_init(&grid, nullptr, -1.0, -1.0), COSLAM_OK);
    const pose2_t sensor_map = {room_.sx, room_.sy, room_.sth};
    ASSERT_EQ(occ_grid_integrate_scan(&grid, sensor_map, r, a, n, nullptr), COSLAM_OK);
    int32_t ix, iy;
    ASSERT_TRUE(occ_grid_cell_of(&grid, 4.01, 1.5, &ix, &iy));
    const double p_wall = std::max({occ_grid_prob(&grid, ix, iy), occ_grid_prob(&grid, ix - 1, iy)});
    EXPECT_GT(p_wall, 0.6); // the wall cell (or its neighbour, within the noise)
    ASSERT_TRUE(occ_grid_cell_of(&grid, 3.75, 1.5, &ix, &iy));
    EXPECT_LT(occ_grid_prob(&grid, ix, iy), 0.5); // free in front of it

    obstacle_params_t op;
    obstacle_params_default(&op);
    const pose2_t sensor_robot = {0.0, 0.0, 0.0};
    obstacle_cmd_t cmd;
    ASSERT_EQ(obstacle_evaluate(&op, sensor_robot, 0.0, r, a, n, &cmd), COSLAM_OK);
    EXPECT_TRUE(cmd.detected);
    EXPECT_NEAR(cmd.nearest_m, 0.5, 0.05);
    EXPECT_NEAR(cmd.line.dist_m, 0.5, 0.01);
    EXPECT_NEAR(cmd.heading_change_rad, -kPi / 2, 0.03); // turn right, parallel to the wall
}

TEST_F(DriverWithEmulator, IdleIsNotAnError)
{
    make(UrgEmulatorConfig{});
    start_md();
    for (int i = 0; i < 5; ++i) EXPECT_EQ(urg_scip2_read_scan(&urg_, &scan_, 0), COSLAM_E_URG_TIMEOUT);
    const urg_scip2_stats_t *s = urg_scip2_stats(&urg_);
    EXPECT_EQ(s->err_timeout + s->err_checksum + s->err_line + s->err_garbage + s->err_echo + s->resyncs, 0u);
}
