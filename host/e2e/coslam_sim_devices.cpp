// coslam-sim-devices - the simulator's world and device emulators as a
// device server for end-to-end runs of real coslam-robot processes
// (docs/e2e.md, issue 10 "How to test without the hardware").
//
// It loads a scenario (sim/world, the camera forced to the geometric
// stand-in), builds the world and one SimRobot per robot exactly as the
// in-process simulator does (same seeds: derive_seed), and runs the physics
// in REAL TIME (simulated t = CLOCK_MONOTONIC - start). For each robot it
// forks and execs one coslam-robot with, on the wire:
//   laser:     a pty; the URG emulator (SCIP 2.0 bytes) on the master side,
//              the robot opens the slave as its [laser] device;
//   drives:    a SOCK_SEQPACKET socketpair carrying struct can_frame: the
//              server's end is bridged to the OmniCanRig's robot endpoint
//              (three CiA 402 drive emulators), the robot's end is inherited
//              (--can-fd), standing in for the SocketCAN socket;
//   sightings: a SOCK_SEQPACKET socketpair, one datagram per camera frame of
//              the SightingOracle (robot_live_open's text format; stamps
//              converted from simulated time to CLOCK_MONOTONIC), inherited
//              (--sightings-fd): a stand-in for the camera (no V4L2
//              device here);
//   GPIO:      a SOCK_SEQPACKET socketpair carrying line states
//              (firmware/port/linux/robot_gpio_fd.h: "P line level" to the
//              robot, "O line level" back), inherited (--gpio-fd), standing
//              in for a GPIO chip ([gpio] required = true): bumper line 0
//              released, e-stop line 1 (active low) released, except that
//              --estop K:T0:T1 presses robot K's e-stop from T0 to T1
//              (simulated seconds); the bumper line follows the simulated
//              body's contact with walls and robots, and --bump K:T0:T1
//              presses it from T0 to T1; the status LED's (line 2) edges
//              are recorded;
//   freeze:    --freeze K:T0:T1 stops robot K's process (SIGSTOP) from T0 to
//              T1 (SIGCONT): a hung controller. Its drives' watchdog must
//              stop the wheels (docs/robot.md "Drive watchdog");
//   link:      Cyclone DDS on loopback between the two robots, authenticated
//              with a fleet key made here (mode 0600).
// Every sample period it records each robot's true pose (moved into its map
// frame, the true start pose) and the robot's own estimate from its status
// JSON; at the end it SIGTERMs the robots (they write a final snapshot),
// loads each snapshot and scores its map with the simulator's evaluate_map.
// Output: OUT/result.json (and OUT/robot<k>.ini, .log, status, store).
//
//   coslam-sim-devices --scenario F --robot BIN --out DIR [--duration S]
//                      [--seed N] [--domain D] [--estop K:T0:T1] [--bump K:T0:T1]
//                      [--freeze K:T0:T1]
// Exit status: 0 the run finished (the numbers are in result.json; judging
// them is the caller's job), 1 a failure of the server or a robot died, 2 usage.
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fcntl.h>
#include <fstream>
#include <linux/can.h>
#include <memory>
#include <poll.h>
#include <sstream>
#include <string>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <termios.h>
#include <unistd.h>
#include <vector>

#include <nlohmann/json.hpp>

#include "checked_file.hpp"
#include "coslam/pose2.h"
#include "hal/hal_storage_linux.h"
#include "robot_snapshot.h"
#include "sim/world/scenario.hpp"
#include "sim/world/sim_robot.hpp"
#include "sim/world/simulation.hpp"
#include "sim/world/world.hpp"
#include "sim_hal/sim_clock.hpp"
#include "sim_hal/sim_link.hpp"

using namespace coslam::sim;

namespace {

constexpr double kDeg = COSLAM_PI / 180.0;
volatile std::sig_atomic_t g_stop = 0;

void on_signal(int)
{
    g_stop = 1;
}

uint64_t mono_us()
{
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<uint64_t>(ts.tv_sec) * 1000000u + static_cast<uint64_t>(ts.tv_nsec) / 1000u;
}

double sq(double v)
{
    return v * v;
}

void die(const std::string &what)
{
    std::fprintf(stderr, "coslam-sim-devices: %s: %s\n", what.c_str(), std::strerror(errno));
    std::exit(1);
}

void write_file(const std::string &path, const std::string &text, mode_t mode)
{
    const int fd = open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, mode);
    if (fd < 0) die("open " + path);
    if (fchmod(fd, mode) != 0) die("chmod " + path);
    if (write(fd, text.data(), text.size()) != static_cast<ssize_t>(text.size())) die("write " + path);
    close(fd);
}

std::string read_file(const std::string &path)
{
    std::ifstream f(path);
    std::stringstream s;
    s << f.rdbuf();
    return s.str();
}

struct Port {
    int pty_master = -1, pty_slave = -1;
    std::string pty_name;
    int can_srv = -1, can_robot = -1;
    int sight_srv = -1, sight_robot = -1;
    int gpio_srv = -1, gpio_robot = -1;
    std::vector<double> led_edges;   // simulated times of the status LED's edges [s]
    bool bumper = false;             // the bumper line's level last sent (active high)
    uint32_t bumper_presses = 0;     // rising edges sent (contacts and --bump)
    uint64_t gpio_bad = 0;
    pid_t pid = -1;
    int exit_status = -1;
    std::vector<uint8_t> urg_out;    // bytes for the pty not yet taken
    uint64_t can_to_rig = 0, can_to_robot = 0, can_dropped = 0;
    uint64_t frames_sent = 0, frames_dropped = 0;
};

void open_pty(Port &p)
{
    p.pty_master = posix_openpt(O_RDWR | O_NOCTTY | O_CLOEXEC);
    if (p.pty_master < 0 || grantpt(p.pty_master) != 0 || unlockpt(p.pty_master) != 0) die("pty");
    p.pty_name = ptsname(p.pty_master);
    // keep the slave open (raw, ours): the master never sees a hang-up
    p.pty_slave = open(p.pty_name.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
    termios tio{};
    if (p.pty_slave < 0 || tcgetattr(p.pty_slave, &tio) != 0) die("pty slave");
    cfmakeraw(&tio);
    tcsetattr(p.pty_slave, TCSANOW, &tio);
    fcntl(p.pty_master, F_SETFL, fcntl(p.pty_master, F_GETFL) | O_NONBLOCK);
}

void open_pair(int &srv, int &robot)
{
    int sv[2];
    if (socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, sv) != 0) die("socketpair");
    srv = sv[0];
    robot = sv[1];
    fcntl(srv, F_SETFL, fcntl(srv, F_GETFL) | O_NONBLOCK);
    // a bounded queue: at most ~1 s of CAN traffic waits in the kernel
    const int sz = 64 * 1024;
    setsockopt(srv, SOL_SOCKET, SO_SNDBUF, &sz, sizeof sz);
}

// The robot's INI: the scenario's settings mapped to coslam-robot's keys
// (what Simulation's constructor gives robot_node_init, key by key).
std::string robot_ini(const Scenario &sc, size_t k, uint64_t seed, const std::string &out, const Port &p,
                      unsigned domain, const std::string &partition)
{
    const RobotSpec &rs = sc.robots[k];
    const FilterNoiseSpec &f = rs.filter_noise;
    std::ostringstream s;
    s.precision(17);
    s << "[robot]\nid = " << k << "\nfleet_size = " << sc.robots.size()
      << "\nstep_period_s = " << sc.control_period_ms / 1000.0
      << "\nstatus_period_s = 0.5\nsnapshot_period_s = 0\nretry_period_s = 0.5\n";
    s << "[laser]\ndevice = " << p.pty_name << "\nfov_rad = " << sc.laser.fov_deg * kDeg
      << "\nmount_x_m = " << sc.laser.mount.x << "\nmount_y_m = " << sc.laser.mount.y
      << "\nmount_theta_rad = " << sc.laser.mount.theta << "\n";
    // GPIO comes over --gpio-fd (no chip); the robot's default lines:
    // bumper 0 (active high), e-stop 1 (active low), status LED 2
    s << "[can]\ninterface =\n[gpio]\nchip =\nrequired = true\n[camera]\ndevice =\nreplay_log =\n";
    s << "[link]\ndomain = " << domain << "\npeers = 127.0.0.1\npartition = " << partition
      << "\nconfig = file://" << out << "/cyclone.xml\n";
    s << "[storage]\ndir = " << out << "/store" << k << "\n";
    s << "[fleet]\nkey_file = " << out << "/fleet.key\nkey_id = 1\n";
    s << "[filter]\ntype = " << slam_filter_kind_name(rs.filter) << "\nparticles = " << rs.particles
      << "\nseed = " << (derive_seed(seed, static_cast<int>(k), 5) & 0xffffffffu) << "\n";
    double rsd = f.range_sd_m.value_or(sc.camera.range_sd_m);
    double bsd = f.bearing_sd_deg.value_or(sc.camera.bearing_sd_deg) * kDeg;
    s << "[slam]\nrange_var_m2 = " << std::max(sq(rsd), 1e-6)
      << "\nrange_var_per_m2 = " << sq(f.range_sd_rel.value_or(sc.camera.range_sd_rel))
      << "\nbearing_var_rad2 = " << std::max(sq(bsd), 1e-8)
      << "\nodo_xy_var_m2_per_m = " << sq(f.odo_xy_sd_m.value_or(rs.noise.odo_xy_sd_m))
      << "\nodo_theta_var_rad2_per_m = " << sq(f.odo_theta_sd_deg.value_or(rs.noise.odo_theta_sd_deg) * kDeg)
      << "\ninit_xy_var_m2 = " << sq(f.init_xy_sd_m.value_or(0.0))
      << "\ninit_theta_var_rad2 = " << sq(f.init_theta_sd_deg.value_or(0.0) * kDeg)
      << "\nlm_init_var_m2 = " << sq(f.lm_init_sd_m.value_or(0.0))
      << "\nsensor_min_range_m = " << sc.camera.min_range_m << "\nsensor_max_range_m = " << sc.camera.max_range_m
      << "\nsensor_fov_rad = " << sc.camera.fov_deg * kDeg << "\n";
    s << "[merge]\nwindow_s = " << sc.meeting.pair_window_ms / 1000.0
      << "\ninterval_s = " << std::fmin(sc.meeting.remerge_s, 4000.0) << "\nmax_range_m = " << sc.meeting.max_range_m
      << "\nmax_sends = " << sc.meeting.max_sends << "\nresend_s = " << sc.meeting.resend_s
      << "\ngap_s = " << sc.meeting.meeting_gap_s << "\nlink_latency_s = " << sc.link.latency_ms / 1000.0
      << "\ngate_chi2 = " << sc.meeting.gate_chi2 << "\nsender_speed_mps = " << sc.meeting.peer_speed_mps
      << "\nsender_turn_radps = " << sc.meeting.peer_turn_dps * kDeg << "\n";
    s << "[behaviour]\ncruise_mps = " << sc.behaviour.cruise_mps
      << "\nmax_turn_radps = " << sc.behaviour.max_turn_dps * kDeg
      << "\nexplore_s = " << rs.explore_s.value_or(sc.behaviour.explore_s) << "\nlinger_s = " << sc.behaviour.linger_s
      << "\n";
    return s.str();
}

// "key": number in a status JSON (nlohmann), NaN if absent or unreadable.
nlohmann::json read_status(const std::string &path)
{
    try {
        return nlohmann::json::parse(read_file(path));
    } catch (...) {
        return nlohmann::json();
    }
}

double num(const nlohmann::json &j, const char *key)
{
    if (!j.is_object() || !j.contains(key)) return NAN;
    const auto &v = j[key];
    if (v.is_number()) return v.get<double>();
    if (v.is_string()) return std::strtod(v.get<std::string>().c_str(), nullptr);
    return NAN;
}

void gpio_pin(Port &p, unsigned line, int level)
{
    const std::string d = "P " + std::to_string(line) + " " + std::to_string(level) + " " + std::to_string(mono_us());
    if (send(p.gpio_srv, d.data(), d.size(), MSG_DONTWAIT) != static_cast<ssize_t>(d.size())) die("gpio send");
}

// Path length of a robot's true track between t0 and t1 [s] (10 ms samples).
double path_m(const std::vector<pose2_t> &h, double t0, double t1, double step_s)
{
    double d = 0.0;
    for (size_t i = static_cast<size_t>(std::max(0.0, t0) / step_s) + 1; i < h.size() && i * step_s <= t1; ++i)
        d += std::hypot(h[i].x - h[i - 1].x, h[i].y - h[i - 1].y);
    return d;
}

// Net heading change from t0 to t1 [deg], the turns summed (wrapped per
// sample), so a turn of more than half a circle is not folded.
double turned_deg(const std::vector<pose2_t> &h, double t0, double t1, double step_s)
{
    double d = 0.0;
    for (size_t i = static_cast<size_t>(std::max(0.0, t0) / step_s) + 1; i < h.size() && i * step_s <= t1; ++i)
        d += std::remainder(h[i].theta - h[i - 1].theta, 2.0 * M_PI);
    return d * 180.0 / M_PI;
}

// Edges per second of the LED in [t0, t1).
double led_rate(const std::vector<double> &edges, double t0, double t1)
{
    const auto k = std::count_if(edges.begin(), edges.end(), [&](double t) { return t >= t0 && t < t1; });
    return t1 > t0 ? static_cast<double>(k) / (t1 - t0) : NAN;
}

// "K:T0:T1" (robot, start, end [s]) of --estop, --bump, --freeze; false
// (and a message) if it does not parse or is not a window
bool parse_window(const std::string &v, const char *opt, const char *what, long &k, double &t0, double &t1)
{
    if (std::sscanf(v.c_str(), "%ld:%lf:%lf", &k, &t0, &t1) != 3 || k < 0 || !(t1 > t0) || t0 < 0.0) {
        std::fprintf(stderr, "coslam-sim-devices: %s needs K:T0:T1 (robot, %s [s])\n", opt, what);
        return false;
    }
    return true;
}

}  // namespace

static int sim_devices_main(int argc, char **argv)
{
    std::string scenario_path, robot_bin, out;
    double duration = -1.0;
    long long seed_opt = -1;
    unsigned domain = 175;
    long estop_robot = -1;
    double estop_t0 = 0.0, estop_t1 = 0.0;
    long bump_robot = -1;
    double bump_t0 = 0.0, bump_t1 = 0.0;
    long freeze_robot = -1;
    double freeze_t0 = 0.0, freeze_t1 = 0.0;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto next = [&]() -> std::string {
            if (i + 1 >= argc) {
                std::fprintf(stderr, "coslam-sim-devices: %s needs a value\n", a.c_str());
                std::exit(2);
            }
            return argv[++i];
        };
        if (a == "--scenario") scenario_path = next();
        else if (a == "--robot") robot_bin = next();
        else if (a == "--out") out = next();
        else if (a == "--duration") duration = std::atof(next().c_str());
        else if (a == "--seed") seed_opt = std::atoll(next().c_str());
        else if (a == "--domain") domain = static_cast<unsigned>(std::atoi(next().c_str()));
        else if (a == "--estop") {
            if (!parse_window(next(), "--estop", "press, release", estop_robot, estop_t0, estop_t1)) return 2;
        } else if (a == "--bump") {
            if (!parse_window(next(), "--bump", "press, release", bump_robot, bump_t0, bump_t1)) return 2;
        } else if (a == "--freeze") {
            if (!parse_window(next(), "--freeze", "SIGSTOP, SIGCONT", freeze_robot, freeze_t0, freeze_t1)) return 2;
        } else {
            std::fprintf(stderr, "usage: coslam-sim-devices --scenario F --robot BIN --out DIR [--duration S] "
                                 "[--seed N] [--domain D] [--estop K:T0:T1] [--bump K:T0:T1] [--freeze K:T0:T1]\n");
            return 2;
        }
    }
    if (scenario_path.empty() || robot_bin.empty() || out.empty()) {
        std::fprintf(stderr, "coslam-sim-devices: --scenario, --robot and --out are required\n");
        return 2;
    }
    Scenario sc;
    try {
        sc = load_scenario_file(scenario_path);
    } catch (const std::exception &e) {
        std::fprintf(stderr, "coslam-sim-devices: %s\n", e.what());
        return 2;
    }
    const uint64_t seed = seed_opt >= 0 ? static_cast<uint64_t>(seed_opt) : sc.seed;
    if (duration <= 0.0) duration = sc.duration_s;
    const size_t n = sc.robots.size();
    if (n < 2 || n > COSLAM_MAX_ROBOTS) {
        std::fprintf(stderr, "coslam-sim-devices: 2..%d robots needed\n", COSLAM_MAX_ROBOTS);
        return 2;
    }
    if (bump_robot >= static_cast<long>(n)) {
        std::fprintf(stderr, "coslam-sim-devices: --bump: no robot %ld\n", bump_robot);
        return 2;
    }
    if (freeze_robot >= static_cast<long>(n)) {
        std::fprintf(stderr, "coslam-sim-devices: --freeze: no robot %ld\n", freeze_robot);
        return 2;
    }
    if (estop_robot >= static_cast<long>(n)) {
        std::fprintf(stderr, "coslam-sim-devices: --estop: no robot %ld\n", estop_robot);
        return 2;
    }
    mkdir(out.c_str(), 0755);
    // out must be absolute: the robots get paths inside it
    char real[4096];
    if (realpath(out.c_str(), real) == nullptr) die("realpath " + out);
    out = real;

    // ---- the world and the robots' devices, as Simulation builds them ----
    World world;
    if (!sc.world.arena.empty()) world.add_polygon(sc.world.arena);
    for (const auto &b : sc.world.boxes) world.add_box(b.center, b.size, b.angle_deg * kDeg);
    for (const auto &p : sc.world.pillars) world.add_pillar(p.center, p.radius_m);
    for (const auto &w : sc.world.walls) world.add_wall(w.from, w.to);
    for (const auto &l : sc.world.landmarks) world.add_landmark(l.pos, static_cast<uint8_t>(l.signature));
    SimClock clock(0);
    SimLinkParams lp;  // unused: the link is DDS; the hub only takes positions
    SimLinkHub hub(clock, n, lp);
    std::vector<std::unique_ptr<SimRobot>> robots;
    for (size_t k = 0; k < n; ++k) {
        const SimRobotConfig rc = robot_config_from_scenario(sc, k, seed);
        robots.push_back(std::make_unique<SimRobot>(clock, world, hub, rc));
    }

    // ---- the wires, the key, the configurations ----
    std::vector<Port> ports(n);
    for (auto &p : ports) {
        open_pty(p);
        open_pair(p.can_srv, p.can_robot);
        open_pair(p.sight_srv, p.sight_robot);
        open_pair(p.gpio_srv, p.gpio_robot);
        gpio_pin(p, 0, 0);  // bumper released (active high)
        gpio_pin(p, 1, 1);  // e-stop released (active low: a closed loop)
    }
    {
        std::string hex;
        std::ifstream ur("/dev/urandom", std::ios::binary);
        for (int i = 0; i < 32; ++i) {
            char b[3];
            std::snprintf(b, sizeof b, "%02x", static_cast<unsigned>(static_cast<unsigned char>(ur.get())));
            hex += b;
        }
        write_file(out + "/fleet.key", hex + "\n", 0600);
        write_file(out + "/cyclone.xml",
                   "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface address=\"127.0.0.1\"/>"
                   "</Interfaces><AllowMulticast>false</AllowMulticast></General>"
                   "<Discovery><MaxAutoParticipantIndex>60</MaxAutoParticipantIndex></Discovery>"
                   "<Tracing><Verbosity>severe</Verbosity><OutputFile>stderr</OutputFile></Tracing></Domain></CycloneDDS>\n",
                   0644);
    }
    const std::string partition = "coslam-e2e-" + std::to_string(getpid());
    for (size_t k = 0; k < n; ++k) {
        write_file(out + "/robot" + std::to_string(k) + ".ini",
                   robot_ini(sc, k, seed, out, ports[k], domain, partition), 0644);
        unlink((out + "/robot" + std::to_string(k) + ".status.json").c_str());
    }

    struct sigaction sa{};
    sa.sa_handler = on_signal;
    sigaction(SIGTERM, &sa, nullptr);
    sigaction(SIGINT, &sa, nullptr);
    signal(SIGPIPE, SIG_IGN);

    // ---- the robots ----
    for (size_t k = 0; k < n; ++k) {
        Port &p = ports[k];
        const std::string ks = std::to_string(k);
        const pid_t pid = fork();
        if (pid < 0) die("fork");
        if (pid == 0) {
            // the robot's two ends survive the exec (they are CLOEXEC here)
            fcntl(p.can_robot, F_SETFD, 0);
            fcntl(p.sight_robot, F_SETFD, 0);
            fcntl(p.gpio_robot, F_SETFD, 0);
            const int lf = open((out + "/robot" + ks + ".log").c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
            if (lf >= 0) {
                dup2(lf, 2);
                dup2(lf, 1);
            }
            const std::string can_fd = std::to_string(p.can_robot), s_fd = std::to_string(p.sight_robot);
            const std::string g_fd = std::to_string(p.gpio_robot);
            const std::string ini = out + "/robot" + ks + ".ini", st = out + "/robot" + ks + ".status.json";
            execl(robot_bin.c_str(), robot_bin.c_str(), "-c", ini.c_str(), "--can-fd", can_fd.c_str(),
                  "--sightings-fd", s_fd.c_str(), "--gpio-fd", g_fd.c_str(), "--status-file", st.c_str(),
                  static_cast<char *>(nullptr));
            _exit(127);
        }
        p.pid = pid;
        close(p.can_robot);
        close(p.sight_robot);
        close(p.gpio_robot);
    }

    // ---- real-time loop ----
    const uint64_t dt_us = std::max<uint64_t>(1, static_cast<uint64_t>(sc.physics_dt_ms * 1000.0));
    const double dt_s = static_cast<double>(dt_us) * 1e-6;
    const uint64_t end_us = static_cast<uint64_t>(duration * 1e6);
    const uint64_t sample_us = 500000;
    const uint64_t t0 = mono_us();
    uint64_t t_sim = 0, next_sample = sample_us, late_max_us = 0, catchups = 0;
    std::vector<std::vector<std::array<double, 9>>> samples(n);  // t, true xyθ (map frame), est xyθ, landmarks, merged
    std::vector<double> first_merge(n, -1.0);
    std::vector<nlohmann::json> last_status(n);
    std::vector<int> team_det(world.landmarks().size(), 0);
    const size_t hist_us = 10000;  // truth in the map frame every 10 ms
    std::vector<std::vector<pose2_t>> truth_hist(n);
    uint8_t buf[8192];
    bool robot_died = false;
    int estop_state = 0;  // 0 before, 1 pressed, 2 released
    int freeze_state = 0; // 0 before, 1 stopped, 2 continued
    // the stop comes at the first moment from T0 on when the robot's wheels
    // turn (at most 3 s late), so that a standing robot cannot pass the
    // check; its length stays T1 - T0
    double freeze_at = 0.0, freeze_end = 0.0, freeze_rpm_at = 0.0, freeze_rpm_max = 0.0;
    uint64_t freeze_consumer0 = 0;
    double freeze_stalls0 = 0.0, freeze_resets0 = 0.0;
    auto wheel_rpm = [&](size_t k) {
        double r = 0.0;
        for (int w = 0; w < 3; ++w) r += std::fabs(robots[k]->rig().drive(w).motor_rpm());
        return r;
    };
    auto consumer_timeouts = [&](size_t k) {
        uint64_t c = 0;
        for (int w = 0; w < 3; ++w) c += robots[k]->rig().drive(w).counters().consumer_timeouts;
        return c;
    };
    while (!g_stop && t_sim < end_us) {
        // the wires, in both directions
        for (size_t k = 0; k < n; ++k) {
            Port &p = ports[k];
            SimRobot &r = *robots[k];
            for (;;) {
                const ssize_t m = read(p.pty_master, buf, sizeof buf);
                if (m <= 0) break;
                (void)hal_serial_write(r.urg().serial(), buf, static_cast<size_t>(m), 0);
            }
            for (;;) {
                can_frame cf{};
                const ssize_t m = recv(p.can_srv, &cf, sizeof cf, MSG_DONTWAIT);
                if (m != static_cast<ssize_t>(sizeof cf)) break;
                hal_can_frame_t f{};
                f.id = cf.can_id & (cf.can_id & CAN_EFF_FLAG ? CAN_EFF_MASK : CAN_SFF_MASK);
                f.flags = static_cast<uint8_t>(((cf.can_id & CAN_EFF_FLAG) ? HAL_CAN_FLAG_EXT : 0u) |
                                               ((cf.can_id & CAN_RTR_FLAG) ? HAL_CAN_FLAG_RTR : 0u));
                f.dlc = cf.can_dlc;
                std::memcpy(f.data, cf.data, 8);
                (void)hal_can_send(r.rig().robot_can(), &f, 0);
                p.can_to_rig++;
            }
            for (;;) {
                char g[64];
                const ssize_t m = recv(p.gpio_srv, g, sizeof g - 1, MSG_DONTWAIT);
                if (m <= 0) break;
                g[m] = '\0';
                unsigned line = 0, level = 0;
                if (std::sscanf(g, "O %u %u", &line, &level) != 2) {
                    p.gpio_bad++;
                } else if (line == 2) {
                    p.led_edges.push_back(static_cast<double>(mono_us() - t0) * 1e-6);
                }
            }
        }
        // the physics, in real time (catching up after a late wake-up)
        const uint64_t now = mono_us() - t0;
        if (now > t_sim + dt_us) late_max_us = std::max(late_max_us, now - t_sim - dt_us);
        int steps = 0;
        while (t_sim + dt_us <= now && t_sim < end_us) {
            t_sim += dt_us;
            clock.advance_to(t_sim);
            for (auto &r : robots) r->physics_step(t_sim, dt_s);
            steps++;
        }
        if (steps > 1) catchups++;
        // the bumper line follows the body's contact with walls and robots
        // (SimRobot::in_contact), or a scripted press (--bump)
        for (size_t k = 0; k < n; ++k) {
            const double ts = static_cast<double>(t_sim) * 1e-6;
            const bool scripted = static_cast<long>(k) == bump_robot && ts >= bump_t0 && ts < bump_t1;
            const bool level = robots[k]->in_contact() || scripted;
            Port &p = ports[k];
            if (level != p.bumper) {
                gpio_pin(p, 0, level ? 1 : 0);
                p.bumper = level;
                if (level) p.bumper_presses++;
            }
        }
        if (freeze_robot >= 0) {
            const double ts = static_cast<double>(t_sim) * 1e-6;
            const size_t fk = static_cast<size_t>(freeze_robot);
            const pid_t fp = ports[fk].pid;
            if (freeze_state == 0 && ts >= freeze_t0 && fp > 0 &&
                (wheel_rpm(fk) > 100.0 || ts >= freeze_t0 + 3.0)) {
                freeze_rpm_at = wheel_rpm(fk);
                freeze_consumer0 = consumer_timeouts(fk);
                freeze_stalls0 = num(last_status[fk], "stalls");
                freeze_resets0 = num(last_status[fk], "stall_resets");
                kill(fp, SIGSTOP);
                freeze_at = ts;
                freeze_end = ts + (freeze_t1 - freeze_t0);
                freeze_state = 1;
            } else if (freeze_state == 1) {
                if (ts >= freeze_at + 0.5) freeze_rpm_max = std::fmax(freeze_rpm_max, wheel_rpm(fk));
                if (ts >= freeze_end && fp > 0) {
                    kill(fp, SIGCONT);
                    freeze_state = 2;
                }
            }
        }
        if (estop_robot >= 0) {
            const double ts = static_cast<double>(t_sim) * 1e-6;
            if (estop_state == 0 && ts >= estop_t0) {
                gpio_pin(ports[static_cast<size_t>(estop_robot)], 1, 0);
                estop_state = 1;
            } else if (estop_state == 1 && ts >= estop_t1) {
                gpio_pin(ports[static_cast<size_t>(estop_robot)], 1, 1);
                estop_state = 2;
            }
        }
        for (size_t k = 0; k < n; ++k) {
            Port &p = ports[k];
            SimRobot &r = *robots[k];
            hal_can_frame_t f{};
            while (hal_can_receive(r.rig().robot_can(), &f, 0) == HAL_OK) {
                can_frame cf{};
                cf.can_id = f.id | ((f.flags & HAL_CAN_FLAG_EXT) ? CAN_EFF_FLAG : 0u) |
                            ((f.flags & HAL_CAN_FLAG_RTR) ? CAN_RTR_FLAG : 0u);
                cf.can_dlc = f.dlc;
                std::memcpy(cf.data, f.data, 8);
                if (send(p.can_srv, &cf, sizeof cf, MSG_DONTWAIT) == static_cast<ssize_t>(sizeof cf)) {
                    p.can_to_robot++;
                } else {
                    p.can_dropped++;
                }
            }
            if (p.urg_out.size() < (1u << 20)) {
                size_t got = 0;
                if (hal_serial_read(r.urg().serial(), buf, sizeof buf, &got, 0) == HAL_OK && got > 0) {
                    p.urg_out.insert(p.urg_out.end(), buf, buf + got);
                }
            }
            if (!p.urg_out.empty()) {
                const ssize_t w = write(p.pty_master, p.urg_out.data(), p.urg_out.size());
                if (w > 0) p.urg_out.erase(p.urg_out.begin(), p.urg_out.begin() + w);
            }
            sighting_frame_t fr{};
            if (sighting_source_next_frame(r.oracle().source(), &fr, 0) == HAL_OK) {
                std::ostringstream s;
                s.precision(9);
                const double ts = static_cast<double>(fr.stamp_us) * 1e-6;
                s << "T " << (t0 + fr.stamp_us) << "\n";
                for (int i = 0; i < fr.n_landmarks; ++i) {
                    s << "S " << ts << ' ' << static_cast<int>(fr.landmarks[i].signature) << ' '
                      << fr.landmarks[i].range_m << ' ' << fr.landmarks[i].bearing_rad << "\n";
                }
                for (int i = 0; i < fr.n_robots; ++i) {
                    s << "R " << ts << ' ' << static_cast<int>(fr.robots[i].robot_id) << ' ' << fr.robots[i].range_m
                      << ' ' << fr.robots[i].bearing_rad << "\n";
                }
                const std::string d = s.str();
                if (send(p.sight_srv, d.data(), d.size(), MSG_DONTWAIT) == static_cast<ssize_t>(d.size())) {
                    p.frames_sent++;
                } else {
                    p.frames_dropped++;
                }
            }
        }
        while (truth_hist[0].size() * hist_us <= t_sim) {
            for (size_t k = 0; k < n; ++k) truth_hist[k].push_back(pose2_between(sc.robots[k].start, robots[k]->pose()));
        }
        if (t_sim >= next_sample) {
            next_sample += sample_us;
            for (size_t k = 0; k < n; ++k) {
                // the estimate is as old as the status file: compare it with
                // the truth at the file's write time (its mtime, moved from
                // CLOCK_REALTIME to our simulated time)
                const std::string sp = out + "/robot" + std::to_string(k) + ".status.json";
                const nlohmann::json st = read_status(sp);
                if (st.is_object()) last_status[k] = st;
                pose2_t tr = pose2_between(sc.robots[k].start, robots[k]->pose());
                double written_s = static_cast<double>(t_sim) * 1e-6;
                struct stat sb{};
                if (stat(sp.c_str(), &sb) == 0) {
                    timespec rt{};
                    clock_gettime(CLOCK_REALTIME, &rt);
                    const int64_t real_now = static_cast<int64_t>(rt.tv_sec) * 1000000 + rt.tv_nsec / 1000;
                    const int64_t written = static_cast<int64_t>(sb.st_mtim.tv_sec) * 1000000 + sb.st_mtim.tv_nsec / 1000;
                    const int64_t sim_w = static_cast<int64_t>(mono_us() - t0) - (real_now - written);
                    if (sim_w >= 0) {
                        const size_t i = std::min(truth_hist[k].size() - 1, static_cast<size_t>(sim_w) / hist_us);
                        tr = truth_hist[k][i];
                        written_s = static_cast<double>(sim_w) * 1e-6;
                    }
                }
                const double merged = num(last_status[k], "mt_merged");
                // the merge happened at most one status period (0.5 s) before this file was written
                if (merged > 0 && first_merge[k] < 0) first_merge[k] = written_s;
                samples[k].push_back({static_cast<double>(t_sim) * 1e-6, tr.x, tr.y, tr.theta,
                                      num(last_status[k], "x"), num(last_status[k], "y"),
                                      num(last_status[k], "theta"), num(last_status[k], "landmarks"), merged});
                int status = 0;
                if (waitpid(ports[k].pid, &status, WNOHANG) == ports[k].pid) {
                    ports[k].exit_status = status;
                    ports[k].pid = -1;
                    robot_died = true;
                    std::fprintf(stderr, "coslam-sim-devices: robot %zu died (status %d) at t=%.1f s\n", k, status,
                                 static_cast<double>(t_sim) * 1e-6);
                    g_stop = 1;
                }
            }
        }
        const uint64_t after = mono_us() - t0;
        const uint64_t due = t_sim + dt_us;
        if (due > after) {
            pollfd pf[4 * COSLAM_MAX_ROBOTS];
            nfds_t m = 0;
            for (auto &p : ports) {
                pf[m++] = {p.pty_master, POLLIN, 0};
                pf[m++] = {p.can_srv, POLLIN, 0};
                pf[m++] = {p.gpio_srv, POLLIN, 0};
            }
            const int wait_ms = static_cast<int>((due - after + 999) / 1000);
            (void)poll(pf, m, wait_ms);
        }
    }
    const double wall_s = static_cast<double>(mono_us() - t0) * 1e-6;

    // ---- stop the robots: SIGTERM, they stop the drives and write a snapshot ----
    // (a robot still stopped by --freeze is continued first, or the SIGTERM
    // would wait in vain)
    if (freeze_state == 1 && ports[static_cast<size_t>(freeze_robot)].pid > 0) {
        kill(ports[static_cast<size_t>(freeze_robot)].pid, SIGCONT);
    }
    for (auto &p : ports) {
        if (p.pid > 0) kill(p.pid, SIGTERM);
    }
    for (auto &p : ports) {
        if (p.pid <= 0) continue;
        for (int i = 0; i < 100; ++i) {
            int status = 0;
            if (waitpid(p.pid, &status, WNOHANG) == p.pid) {
                p.exit_status = status;
                p.pid = -1;
                break;
            }
            usleep(50000);
        }
        if (p.pid > 0) {
            kill(p.pid, SIGKILL);
            waitpid(p.pid, &p.exit_status, 0);
            p.pid = -1;
        }
    }

    // ---- evaluation ----
    for (size_t k = 0; k < n; ++k) {
        const auto &det = robots[k]->oracle().detections();
        for (size_t j = 0; j < det.size() && j < team_det.size(); ++j) team_det[j] += det[j];
    }
    std::vector<uint8_t> truth_sig;
    for (const auto &l : world.landmarks()) truth_sig.push_back(l.signature);
    nlohmann::json res;
    res["scenario"] = {{"name", sc.name}, {"source", sc.source}, {"seed", seed}, {"duration_s", duration}};
    res["timing"] = {{"sim_s", static_cast<double>(t_sim) * 1e-6}, {"wall_s", wall_s},
                     {"late_max_ms", static_cast<double>(late_max_us) * 1e-3}, {"catchups", catchups}};
    res["robots"] = nlohmann::json::array();
    for (size_t k = 0; k < n; ++k) {
        const Port &p = ports[k];
        nlohmann::json rj;
        rj["id"] = k;
        rj["filter"] = slam_filter_kind_name(sc.robots[k].filter);
        rj["exit_status"] = p.exit_status;
        rj["clean_exit"] = WIFEXITED(p.exit_status) && WEXITSTATUS(p.exit_status) == 0;
        rj["distance_m"] = robots[k]->distance_m();
        rj["wall_collisions"] = robots[k]->wall_collisions();
        rj["robot_collisions"] = robots[k]->robot_collisions();
        // null: never merged (as coslam-sim's metrics.json)
        rj["first_merge_s"] = first_merge[k] >= 0 ? nlohmann::json(first_merge[k]) : nlohmann::json(nullptr);
        rj["wire"] = {{"can_to_drives", p.can_to_rig},     {"can_to_robot", p.can_to_robot},
                      {"can_dropped", p.can_dropped},      {"frames_sent", p.frames_sent},
                      {"frames_dropped", p.frames_dropped}, {"urg_scans_ok", num(last_status[k], "urg_scans_ok")}};
        rj["status"] = last_status[k];
        // GPIO: the status LED (heartbeat 4 edges/s running, fast blink 8
        // edges/s stopped) and, for the e-stopped robot, its motion
        const double hs = static_cast<double>(hist_us) * 1e-6;
        const double run_s = static_cast<double>(t_sim) * 1e-6;
        rj["gpio"] = {{"bad_datagrams", p.gpio_bad}, {"led_edges", p.led_edges.size()},
                      {"led_rate_hz", led_rate(p.led_edges, 5.0, run_s)}, {"bumper_presses", p.bumper_presses}};
        if (static_cast<long>(k) == bump_robot) {
            // pressed: stopped like the e-stop; released: the latch is
            // acknowledged and the behaviour turns a quarter right
            rj["gpio"]["bump"] = {{"t0_s", bump_t0}, {"t1_s", bump_t1},
                                  {"moved_during_m", path_m(truth_hist[k], bump_t0 + 0.5, bump_t1, hs)},
                                  {"turned_after_deg", turned_deg(truth_hist[k], bump_t1, bump_t1 + 4.0, hs)},
                                  {"moved_after_m", path_m(truth_hist[k], bump_t1 + 0.5, bump_t1 + 4.5, hs)}};
        }
        if (static_cast<long>(k) == freeze_robot && freeze_state == 2) {
            // the process stopped: the drives' watchdog (200 ms) and their
            // quick stop, then still; continued: the stall noticed, the
            // drive fault reset at once, driving again
            rj["freeze"] = {{"t0_s", freeze_at},
                            {"t1_s", freeze_end},
                            {"wheel_rpm_at_stop", freeze_rpm_at},
                            {"wheel_rpm_max_stopped", freeze_rpm_max},
                            {"consumer_timeouts", consumer_timeouts(k) - freeze_consumer0},
                            {"moved_before_m", path_m(truth_hist[k], freeze_at - 1.0, freeze_at, hs)},
                            {"moved_first_m", path_m(truth_hist[k], freeze_at, freeze_at + 0.5, hs)},
                            {"moved_during_m", path_m(truth_hist[k], freeze_at + 0.5, freeze_end, hs)},
                            {"moved_after_m", path_m(truth_hist[k], freeze_end + 1.5, freeze_end + 4.0, hs)},
                            {"stalls", num(last_status[k], "stalls") - freeze_stalls0},
                            {"stall_resets", num(last_status[k], "stall_resets") - freeze_resets0}};
        }
        if (static_cast<long>(k) == estop_robot) {
            const double len = estop_t1 - estop_t0;
            // 0.5 s to stop: the next control step commands zero, the
            // drives' deceleration ramp, the base's inertia
            rj["gpio"]["estop"] = {{"t0_s", estop_t0}, {"t1_s", estop_t1},
                                   {"moved_before_m", path_m(truth_hist[k], estop_t0 - len, estop_t0, hs)},
                                   {"moved_during_m", path_m(truth_hist[k], estop_t0 + 0.5, estop_t1, hs)},
                                   {"moved_after_m", path_m(truth_hist[k], estop_t1 + 0.5, estop_t1 + 0.5 + len, hs)},
                                   {"led_rate_before_hz", led_rate(p.led_edges, estop_t0 - len, estop_t0)},
                                   {"led_rate_during_hz", led_rate(p.led_edges, estop_t0 + 0.5, estop_t1)}};
        }
        // pose error over the run (estimate from the status file, <= 0.5 s old)
        double se = 0.0, fin = NAN, fin_h = NAN;
        int m = 0;
        for (const auto &s : samples[k]) {
            if (!std::isfinite(s[4])) continue;
            const double e = std::hypot(s[1] - s[4], s[2] - s[5]);
            se += e * e;
            m++;
            fin = e;
            fin_h = std::fabs(std::remainder(s[3] - s[6], 2.0 * COSLAM_PI)) / kDeg;
        }
        rj["pose_rmse_m"] = m > 0 ? std::sqrt(se / m) : NAN;
        rj["final_pos_err_m"] = fin;
        rj["final_heading_err_deg"] = fin_h;
        // the final map: the shutdown snapshot
        hal_storage_linux_t stor{};
        auto snap = std::make_unique<robot_snapshot_t>();
        if (hal_storage_linux_open_reader(&stor, (out + "/store" + std::to_string(k)).c_str()) == HAL_OK) {
            auto snaps = std::make_unique<robot_snapshots_t>();
            robot_snapshots_init(snaps.get(), &stor.dev);
            const char *name = nullptr;
            if (robot_snapshots_load(snaps.get(), snap.get(), &name, nullptr) == COSLAM_OK) {
                std::vector<point2_t> truth;
                for (const auto &l : world.landmarks())
                    truth.push_back(pose2_apply_inverse(sc.robots[k].start, point2_t{l.p.x(), l.p.y()}));
                map_eval_t ev{};
                evaluate_map(snap->map, truth, truth_sig, team_det, sc.evaluation.min_seen, sc.evaluation.gate_m,
                             &ev);
                const pose2_t tr = pose2_between(sc.robots[k].start, robots[k]->pose());
                rj["final_map"] = {{"n_estimated", ev.n_estimated}, {"n_matched", ev.n_matched},
                                   {"n_missed", ev.n_missed},       {"n_spurious", ev.n_spurious},
                                   {"rmse_m", ev.rmse_m},           {"max_err_m", ev.max_err_m}};
                rj["final_pos_err_m"] = std::hypot(snap->map.pose.x - tr.x, snap->map.pose.y - tr.y);
                rj["final_heading_err_deg"] =
                    std::fabs(std::remainder(snap->map.pose.theta - tr.theta, 2.0 * COSLAM_PI)) / kDeg;
            }
            hal_storage_close(&stor.dev);
        }
        res["robots"].push_back(rj);
    }
    int wrote = 1;
    try {
        coslam::cli::write_text_file(out + "/result.json", res.dump(2) + "\n");
    } catch (const coslam::cli::WriteError &e) {
        // the run's numbers are in that file only: an exit 0 would hide them lost
        std::fprintf(stderr, "coslam-sim-devices: %s\n", e.what());
        wrote = 0;
    }
    if (wrote) {
        std::printf("coslam-sim-devices: %.1f s simulated in %.1f s wall (late max %.1f ms); result in %s/result.json\n",
                    static_cast<double>(t_sim) * 1e-6, wall_s, static_cast<double>(late_max_us) * 1e-3, out.c_str());
    }
    for (auto &p : ports) {
        close(p.pty_master);
        close(p.pty_slave);
        close(p.can_srv);
        close(p.sight_srv);
        close(p.gpio_srv);
    }
    return robot_died || !wrote ? 1 : 0;
}

// exit status with standard output checked (stdout_check.h)
int main(int argc, char **argv)
{
    return coslam::cli::stdout_exit("coslam-sim-devices", sim_devices_main(argc, argv));
}
