// urg_pty_bridge - the simulator's URG-04LX emulator (sim/devices/urg) on a
// pseudo-terminal, in real time: a stand-in laser for coslam-robot tests and
// for tools/robot_cpu.sh. The robot opens the pty like /dev/ttyACM0 and
// talks SCIP 2.0 to it byte for byte.
//
//   urg_pty_bridge LINK   creates a pty, makes LINK a symbolic link to its
//                         slave side, and serves until SIGTERM / SIGINT
//                         (then removes LINK).
//
// The scene: the sensor stands 0.12 m ahead of the centre of a robot at the
// origin, facing +x, in a 6 m x 5 m room ([-2, 4] x [-2.5, 2.5]) with a
// pillar of radius 0.2 m at (1.5, 0.8). Simulated time = real time since
// start. Output the pty cannot take now is kept and sent later (up to the
// emulator's own 1 MB queue, beyond which it drops, like a full USB buffer).
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fcntl.h>
#include <poll.h>
#include <string>
#include <termios.h>
#include <unistd.h>
#include <vector>

#include "urg/urg_emulator.h"

namespace {

volatile std::sig_atomic_t g_stop = 0;

void on_signal(int)
{
    g_stop = 1;
}

uint64_t now_us()
{
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<uint64_t>(ts.tv_sec) * 1000000u + static_cast<uint64_t>(ts.tv_nsec) / 1000u;
}

// Distance from the sensor along angle a (sensor frame) to the room's walls
// or the pillar.
double range_m(double a)
{
    const double sx = 0.12, sy = 0.0;
    const double dx = std::cos(a), dy = std::sin(a);
    double best = INFINITY;
    auto wall_x = [&](double x) {
        if (std::fabs(dx) > 1e-12) {
            const double t = (x - sx) / dx;
            if (t > 0) best = std::fmin(best, t);
        }
    };
    auto wall_y = [&](double y) {
        if (std::fabs(dy) > 1e-12) {
            const double t = (y - sy) / dy;
            if (t > 0) best = std::fmin(best, t);
        }
    };
    wall_x(-2.0);
    wall_x(4.0);
    wall_y(-2.5);
    wall_y(2.5);
    // pillar: |s + t d - c| = r
    const double cx = 1.5 - sx, cy = 0.8 - sy, r = 0.2;
    const double b = dx * cx + dy * cy;
    const double c = cx * cx + cy * cy - r * r;
    const double disc = b * b - c;
    if (disc >= 0.0) {
        const double t = b - std::sqrt(disc);
        if (t > 0) best = std::fmin(best, t);
    }
    return best;
}

} // namespace

int main(int argc, char **argv)
{
    if (argc != 2) {
        std::fprintf(stderr, "usage: urg_pty_bridge LINK\n");
        return 2;
    }
    const std::string link = argv[1];
    const int master = posix_openpt(O_RDWR | O_NOCTTY);
    if (master < 0 || grantpt(master) != 0 || unlockpt(master) != 0) {
        std::perror("urg_pty_bridge: pty");
        return 1;
    }
    const char *slave_name = ptsname(master);
    // keep the slave open (raw) so that the master never sees a hang-up
    // between two robot processes
    const int slave = open(slave_name, O_RDWR | O_NOCTTY);
    termios tio{};
    if (slave < 0 || tcgetattr(slave, &tio) != 0) {
        std::perror("urg_pty_bridge: slave");
        return 1;
    }
    cfmakeraw(&tio);
    tcsetattr(slave, TCSANOW, &tio);
    fcntl(master, F_SETFL, fcntl(master, F_GETFL) | O_NONBLOCK);
    unlink(link.c_str());
    if (symlink(slave_name, link.c_str()) != 0) {
        std::perror("urg_pty_bridge: symlink");
        return 1;
    }
    struct sigaction sa{};
    sa.sa_handler = on_signal;
    sigaction(SIGTERM, &sa, nullptr);
    sigaction(SIGINT, &sa, nullptr);

    coslam::sim::UrgEmulatorConfig cfg;
    cfg.seed = 5;
    coslam::sim::UrgEmulator emu(cfg, range_m);
    hal_serial_t *dev = emu.serial();
    const uint64_t t0 = now_us();
    std::vector<uint8_t> pending;
    uint8_t buf[4096];
    while (!g_stop) {
        pollfd p{master, POLLIN, 0};
        (void)poll(&p, 1, 1);
        for (;;) {
            const ssize_t n = read(master, buf, sizeof buf);
            if (n <= 0) break;
            (void)hal_serial_write(dev, buf, static_cast<size_t>(n), 0);
        }
        emu.set_time_us(now_us() - t0);
        if (pending.empty()) {
            size_t got = 0;
            if (hal_serial_read(dev, buf, sizeof buf, &got, 0) == HAL_OK && got > 0) {
                pending.assign(buf, buf + got);
            }
        }
        if (!pending.empty()) {
            const ssize_t w = write(master, pending.data(), pending.size());
            if (w > 0) pending.erase(pending.begin(), pending.begin() + w);
        }
    }
    unlink(link.c_str());
    close(slave);
    close(master);
    return 0;
}
