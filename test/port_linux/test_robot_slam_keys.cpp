// One settings source: a [slam] section means the same to coslam-robot and
// coslam-replay. Both read it through the key table of app/slam_params_ini.h;
// this test checks it end to end, across the two tools: random [slam]
// sections (every key, values of random precision and notation) are loaded
// by the replay library and by the robot binary (--print-config, whose
// output is read back), and every field must be bit-identical; bad sections
// are refused by both, at the same line.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <sys/wait.h>
#include <unistd.h>

#include "app/slam_params_ini.h"
#include "replay_config.h"
#include "replay_data.h"

using namespace coslam::replay;

namespace {

struct RobotRun {
    int status = -1;
    std::string out;
    std::string err;
};

std::string temp_dir()
{
    char d[] = "/tmp/coslam-slamkeys-XXXXXX";
    if (mkdtemp(d) == nullptr) {
        ADD_FAILURE() << "mkdtemp";
        return "/tmp";
    }
    return d;
}

std::string slurp(const std::string &path)
{
    std::ifstream f(path);
    std::stringstream ss;
    ss << f.rdbuf();
    return ss.str();
}

// coslam-robot -c <text as a file> --print-config
RobotRun robot_print(const std::string &dir, const std::string &text)
{
    const std::string ini = dir + "/robot.ini";
    std::ofstream(ini) << text;
    const std::string cmd = std::string(COSLAM_ROBOT_BIN) + " -c " + ini + " --print-config >" + dir + "/out 2>" +
                            dir + "/err";
    RobotRun r;
    const int st = std::system(cmd.c_str());
    r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
    r.out = slurp(dir + "/out");
    r.err = slurp(dir + "/err");
    return r;
}

// The [slam] section of an INI text (header included).
std::string slam_section(const std::string &ini)
{
    const size_t a = ini.find("[slam]");
    if (a == std::string::npos) return "";
    const size_t b = ini.find("\n[", a + 1);
    return ini.substr(a, b == std::string::npos ? std::string::npos : b + 1 - a);
}

slam_params_t replay_slam(const std::string &text)
{
    ReplayConfig c = replay_config_default();
    replay_config_load_string(c, text, "x.ini");
    return c.slam;
}

void expect_identical(const slam_params_t &a, const slam_params_t &b, const std::string &text)
{
    for (size_t i = 0; i < slam_params_ini_count(); ++i) {
        const slam_params_ini_key_t *k = slam_params_ini_key(i);
        const double va = slam_params_ini_get(&a, k);
        const double vb = slam_params_ini_get(&b, k);
        EXPECT_EQ(std::memcmp(&va, &vb, sizeof va), 0) << k->name << ": " << va << " vs " << vb << "\n" << text;
    }
}

// A value inside the key's domain, written with random precision/notation.
std::string value_text(std::mt19937_64 &rng, double lo, double hi)
{
    std::uniform_real_distribution<double> u(lo, hi);
    const double v = u(rng);
    std::uniform_int_distribution<int> prec(1, 17);
    std::uniform_int_distribution<int> style(0, 2);
    char buf[64];
    const int p = prec(rng);
    switch (style(rng)) {
    case 0: std::snprintf(buf, sizeof buf, "%.*g", p, v); break;
    case 1: std::snprintf(buf, sizeof buf, "%.*e", p, v); break;
    default: std::snprintf(buf, sizeof buf, "%.*f", p, v); break;
    }
    // a short notation can round out of the domain ("%.1f" of 0.03 is 0.0)
    const double back = std::strtod(buf, nullptr);
    if (!(back >= lo && back <= hi)) {
        std::snprintf(buf, sizeof buf, "%.17g", v);
    }
    return buf;
}

std::string random_section(std::mt19937_64 &rng)
{
    std::ostringstream s;
    s << "[slam]\n";
    for (size_t i = 0; i < slam_params_ini_count(); ++i) {
        const slam_params_ini_key_t *k = slam_params_ini_key(i);
        const std::string n = k->name;
        double lo = std::isfinite(k->min) ? k->min : -50.0;
        double hi = std::isfinite(k->max) && k->max < 1e6 ? k->max : lo + 20.0;
        // the rules between keys: min < max range, gate <= new-landmark gate,
        // exist_init <= exist_confirm <= exist_max, sensor_min_range_m <
        // sighting_max_range_m
        if (n == "sensor_min_range_m") { lo = 0.0; hi = 1.0; }
        if (n == "sensor_max_range_m") { lo = 2.0; hi = 9.0; }
        if (n == "gate_chi2") { lo = 1.0; hi = 10.0; }
        if (n == "new_landmark_chi2") { lo = 11.0; hi = 40.0; }
        if (n == "exist_init") { lo = 0.0; hi = 2.0; }
        if (n == "exist_confirm") { lo = 3.0; hi = 6.0; }
        if (n == "exist_max") { lo = 7.0; hi = 12.0; }
        if (n == "sensor_fov_rad") { lo = 0.1; hi = 6.2; }
        if (n == "visibility_margin") { lo = 0.05; hi = 1.0; }
        if (n == "sighting_max_range_m") { lo = 1.5; hi = 30.0; }
        if (k->min_open && lo <= k->min) lo = k->min + 1e-3;
        if (n.find("var") != std::string::npos) { hi = std::min(hi, lo + 0.5); } // bearing_var_rad2 <= 0.25
        s << n << " = " << value_text(rng, lo, hi) << "\n";
    }
    return s.str();
}

// "name:LINE:" -> LINE, or -1.
int line_of(const std::string &msg, const std::string &name)
{
    const size_t a = msg.find(name + ":");
    if (a == std::string::npos) return -1;
    return std::atoi(msg.c_str() + a + name.size() + 1);
}

} // namespace

TEST(RobotSlamKeys, RandomSectionsParseBitIdentically)
{
    const std::string dir = temp_dir();
    std::mt19937_64 rng(20240601u);
    const int n = COSLAM_TEST_FULL ? 200 : 40;
    for (int k = 0; k < n; ++k) {
        const std::string text = random_section(rng);
        slam_params_t by_replay{};
        ASSERT_NO_THROW(by_replay = replay_slam(text)) << text;
        const RobotRun r = robot_print(dir, text);
        ASSERT_EQ(r.status, 0) << r.err << "\n" << text;
        const std::string printed = slam_section(r.out);
        ASSERT_FALSE(printed.empty()) << r.out;
        slam_params_t by_robot{};
        ASSERT_NO_THROW(by_robot = replay_slam(printed)) << printed;
        expect_identical(by_replay, by_robot, text);
    }
    std::system(("rm -rf " + dir).c_str());
}

TEST(RobotSlamKeys, BadSectionsAreRefusedByBothAtTheSameLine)
{
    const std::string dir = temp_dir();
    const char *bad[] = {
        "[slam]\nrange_var_m2 = 0.01\nrange_var_m3 = 1\n",    // unknown key
        "[slam]\n\ngate_chi2 = abc\n",                         // not a number
        "[slam]\ngate_chi2 = 1e999\n",                         // out of double range
        "[slam]\nbearing_var_rad2 = 0\n",                      // outside (0, inf)
        "[slam]\n# c\nvisibility_margin = 1.01\n",             // outside (0, 1]
        "[slam]\nexist_hit = -1\n",                            // float key outside [0, max]
        "[slam]\nsensor_fov_rad = 6.3\n",                      // outside (0, 6.2832]
        "[slam]\nodo_xy_var_m2_per_m = 0.1x\n",                // trailing characters
    };
    for (const char *text : bad) {
        std::string replay_msg;
        try {
            (void)replay_slam(text);
        } catch (const ReplayError &e) {
            replay_msg = e.what();
        }
        ASSERT_FALSE(replay_msg.empty()) << "replay accepted:\n" << text;
        const RobotRun r = robot_print(dir, text);
        EXPECT_EQ(r.status, 2) << text;
        const int lr = line_of(replay_msg, "x.ini");
        const int lb = line_of(r.err, dir + "/robot.ini");
        EXPECT_GT(lr, 0) << replay_msg;
        EXPECT_EQ(lr, lb) << "replay: " << replay_msg << "\nrobot: " << r.err;
        // the same reason words (each tool adds its own prefix)
        const size_t colon = replay_msg.rfind(": ");
        ASSERT_NE(colon, std::string::npos);
        EXPECT_NE(r.err.find(replay_msg.substr(colon + 2)), std::string::npos)
            << "replay: " << replay_msg << "\nrobot: " << r.err;
    }
    std::system(("rm -rf " + dir).c_str());
}

TEST(RobotSlamKeys, OneTableCoversTheStruct)
{
    // every field of slam_params_t is a key exactly once, in field order
    size_t bytes = 0;
    for (size_t i = 0; i < slam_params_ini_count(); ++i) {
        const slam_params_ini_key_t *k = slam_params_ini_key(i);
        bytes += k->type == SLAM_PARAMS_INI_FLOAT ? sizeof(float) : sizeof(double);
        if (i > 0) {
            EXPECT_GT(k->offset, slam_params_ini_key(i - 1)->offset) << k->name;
        }
        EXPECT_EQ(slam_params_ini_find(k->name), k);
    }
    // the struct is these fields and its padding only
    EXPECT_LE(bytes, sizeof(slam_params_t));
    EXPECT_GE(bytes + 8, sizeof(slam_params_t));
}
